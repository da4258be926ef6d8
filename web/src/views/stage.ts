/**
 * A ready three.js stage for a character: renderer, camera, lights, a 1 m floor grid, optional
 * floor shadows, resize handling (the element, the demo, the viewer and the VR page use it).
 */
import * as THREE from 'three';
import { mark } from '../fetch.ts';
import { FloorGrid } from './floor-grid.ts';
import { rememberRenderer, softwareWebGL } from './software-gl.ts';

/**
 * Compiles and links the shaders of everything visible under `object` now, as it will be drawn in
 * `scene`, instead of in the frame that first draws it. Why now: ANGLE links a program only when
 * it is first used or asked about, so `renderer.compile` alone leaves the wait for that frame —
 * on a software GPU a second or more per program, a frozen page. Asking for each program's
 * uniforms makes three.js wait for the link here (where the page is loading anyway). For unlit
 * materials, or once the scene has drawn its shadows: compiled before the first shadow pass, lit
 * materials drew with a non-shadow placeholder in their shadow samplers (WebGL errors at every
 * draw) — draw a frame (`Stage.render`) instead.
 */
export function compileNow(renderer: THREE.WebGLRenderer, object: THREE.Object3D, camera: THREE.Camera, scene: THREE.Scene | null = null): void {
  // Its uniforms and attributes asked for now (three.js asks at its first draw).
  for (const material of renderer.compile(object, camera, scene)) {
    const program = (renderer.properties.get(material) as { currentProgram?: { getUniforms(): unknown; getAttributes(): unknown } }).currentProgram;
    program?.getUniforms();
    program?.getAttributes();
  }
}

const _size = new THREE.Vector2();
const _scissor = new THREE.Vector4();

export class Stage {
  readonly renderer: THREE.WebGLRenderer;
  readonly scene = new THREE.Scene();
  readonly camera: THREE.PerspectiveCamera;
  readonly grid = new FloorGrid(20);
  readonly sun: THREE.DirectionalLight;
  /** Catches shadows on the floor (invisible otherwise); see `enableShadows`. */
  private shadowCatcher: THREE.Mesh | null = null;

  private readonly observer: ResizeObserver | null = null;

  /**
   * A canvas for `container` (appended with the first frame), sized to it (and kept so).
   * `antialias`: MSAA (default: on a GPU, off where WebGL draws in software).
   */
  constructor(
    private readonly container: HTMLElement,
    options: { antialias?: boolean } = {},
  ) {
    // MSAA and high-DPI pixels on a GPU; neither where WebGL draws in software (software-gl.ts).
    const software = softwareWebGL();
    // The drawing buffer is not kept (WebGL's default): a kept one is copied for the compositor
    // every frame (a resolve and a copy on a tiled mobile GPU). Nothing reads the canvas back.
    this.renderer = new THREE.WebGLRenderer({ antialias: options.antialias ?? !software });
    rememberRenderer(this.renderer.getContext());
    this.renderer.setPixelRatio(software ? 1 : Math.min(window.devicePixelRatio, 2));
    // Output in sRGB: three.js' default, not set again — its setter writes the context's colour
    // spaces, a wait for the GPU process (~5 ms traced) that changes nothing.
    // Asked for now, with three.js' own extensions, while the GPU process is idle: three.js asks
    // at the first texture's upload, where the answer waited behind the avatar's programs (~10 ms).
    this.renderer.extensions.has('EXT_texture_filter_anisotropic');
    // Set once, before anything is drawn: the shadow type is part of every lit material's program
    // key, and three.js does not recompile a material already drawn when it changes — so a type
    // set later (by enableShadows) gave every avatar loaded after it a second set of programs, each
    // a compile (seconds on a software GPU) that a room's late joiner waited for.
    // (PCF: three.js r18x dropped PCFSoft, warning and using PCF in its place.)
    this.renderer.shadowMap.type = THREE.PCFShadowMap;
    // The canvas joins the page with its first frame (`render`), not before: an empty canvas in
    // the page is one more layer each frame the browser draws while the page loads (read back
    // from the GPU, ~15 ms a frame, where compositing is done in software).

    this.scene.background = new THREE.Color(0x1d2126);
    this.scene.fog = new THREE.Fog(0x1d2126, 8, 20);

    this.camera = new THREE.PerspectiveCamera(45, 1, 0.05, 200);
    this.camera.position.set(1.5, 1.4, 2.3);

    const hemi = new THREE.HemisphereLight(0xdde8ff, 0x30281e, 1.4);
    this.scene.add(hemi);
    const sun = new THREE.DirectionalLight(0xffffff, 2.0);
    sun.position.set(3, 6, 4);
    this.sun = sun;
    this.scene.add(sun, sun.target);

    this.scene.add(this.grid.object);

    this.resize();
    if (typeof ResizeObserver !== 'undefined') {
      this.observer = new ResizeObserver(() => this.resize());
      this.observer.observe(container);
    }
    mark('mm:stage-ready'); // its WebGL context made: a step load benchmarks print (scripts/bench-load.mjs)
  }

  /** Frees the renderer and every geometry, material and texture in the scene. */
  dispose(): void {
    this.observer?.disconnect();
    this.renderer.setAnimationLoop(null);
    this.scene.traverse((o) => {
      const m = o as THREE.Mesh;
      m.geometry?.dispose();
      for (const mat of Array.isArray(m.material) ? m.material : m.material ? [m.material] : []) {
        for (const v of Object.values(mat)) if (v instanceof THREE.Texture) v.dispose();
        mat.dispose();
      }
    });
    this.renderer.dispose();
    this.renderer.forceContextLoss();
    this.renderer.domElement.remove();
  }

  /** Soft shadows of casters (meshes with `castShadow`) on the floor, in a box around `follow`'s point. */
  enableShadows(on: boolean): void {
    this.renderer.shadowMap.enabled = on;
    this.sun.castShadow = on;
    if (on && !this.shadowCatcher) {
      const s = this.sun.shadow;
      s.mapSize.set(1024, 1024);
      s.camera.left = s.camera.bottom = -3;
      s.camera.right = s.camera.top = 3;
      s.camera.near = 1;
      s.camera.far = 20;
      s.bias = -0.0005;
      this.shadowCatcher = new THREE.Mesh(new THREE.PlaneGeometry(200, 200), new THREE.ShadowMaterial({ opacity: 0.35 }));
      this.shadowCatcher.rotation.x = -Math.PI / 2;
      this.shadowCatcher.receiveShadow = true;
      this.scene.add(this.shadowCatcher);
    }
    if (this.shadowCatcher) this.shadowCatcher.visible = on;
  }

  /**
   * Keeps the floor grid and the sun's shadow box (±3 m) around floor point (x, z): the character
   * walking off the box lost its shadow.
   */
  follow(x: number, z: number): void {
    this.grid.follow(x, z);
    this.sun.position.set(x + 3, 6, z + 4);
    this.sun.target.position.set(x, 0, z);
  }

  resize(): void {
    const w = Math.max(1, this.container.clientWidth);
    const h = Math.max(1, this.container.clientHeight);
    // The observer's first call repeats the constructor's size: setting a canvas' size, even to
    // the same one, clears and reallocates its drawing buffer.
    const size = this.renderer.getSize(_size);
    if (size.x === w && size.y === h) return;
    this.renderer.setSize(w, h);
    this.camera.aspect = w / h;
    this.camera.updateProjectionMatrix();
  }

  /**
   * Gets `object` (not yet in the scene) ready to draw: its programs compiled and linked
   * (`compileNow`), then drawn once in this scene, unseen — the canvas joins the page with the
   * first real frame, which draws over it. Why the draw: a GPU builds a program's pipeline for the
   * state it is drawn in only at its first draw, and on a software GPU (ANGLE on SwiftShader) that
   * is a compile of its own, 20-60 ms per program. Inside a frame each next program's first query
   * waited for the draw before it; drawn here, after every program has answered its queries, the
   * GPU process builds them while this thread goes on (the embed page's warm visit: the first
   * frame's ~50-80 ms of waits for the GPU gone from its main thread). Its textures upload here too.
   * Judged by when the first frame is shown, not only drawn: docs/history.md "Loading", stop 57.
   * Once the canvas is in the page (after the first `render`), or for an object in a scene of its
   * own, it only compiles. Worth it only while something else is still loading: a first frame
   * that follows at once links its programs itself (`render`), and drawn unseen just before it
   * the pipelines were built for the unseen draw and the first frame was shown later (stop 59).
   * Only for a scene without shadows: see `compileNow`.
   */
  warmUp(object: THREE.Object3D): void {
    const renderer = this.renderer;
    compileNow(renderer, object, this.camera, this.scene);
    // A drawn canvas would show the unposed object for a frame; someone else's object is not ours to move.
    if (object.parent || renderer.domElement.parentNode) return;
    // Into one pixel: the pipelines are the same (viewport and scissor are not part of them) and a
    // software GPU rasterizes next to nothing before the first real frame can be read back.
    const scissor = renderer.getScissor(_scissor);
    const scissorTest = renderer.getScissorTest();
    renderer.setScissor(0, 0, 1, 1);
    renderer.setScissorTest(true);
    this.scene.add(object);
    renderer.render(this.scene, this.camera);
    this.scene.remove(object);
    renderer.setScissorTest(scissorTest);
    renderer.setScissor(scissor);
    renderer.getContext().flush();
  }

  render(): void {
    // The first frame links every program it draws before its first draw: linked among its draws,
    // each link's queries waited for the GPU process to build the pipelines of the draws before
    // it (the demo's warm visit, traced: 110 ms of the first frame, a software GPU). Not with
    // shadows on: see `compileNow`.
    // One object per material (a crowd's characters share theirs; compiling each walks the scene).
    const first = !this.renderer.domElement.parentNode;
    if (first && !this.renderer.shadowMap.enabled) {
      const seen = new Set<THREE.Material | THREE.Material[]>();
      this.scene.traverseVisible((o) => {
        const drawn = o as THREE.Mesh;
        if (!(drawn.isMesh || (o as THREE.Line).isLine || (o as THREE.Points).isPoints) || seen.has(drawn.material)) return;
        seen.add(drawn.material);
        compileNow(this.renderer, o, this.camera, this.scene);
      });
    }
    this.renderer.render(this.scene, this.camera);
    if (first) this.container.appendChild(this.renderer.domElement);
  }
}
