/**
 * The spectator view on the desktop page while the headset presents (issue 6, views): three.js
 * renders only the headset's eyes during a session, so the page gets a second renderer on its
 * own canvas, drawing the same scene from a third-person camera that follows the avatar. Shown
 * as a picture-in-picture over the page (an emulator may draw the eyes' view on the main canvas).
 */
import * as THREE from 'three';
import { rememberRenderer, softwareWebGL } from '../views/software-gl.ts';

export class SpectatorView {
  private renderer_: THREE.WebGLRenderer | null = null;
  readonly camera = new THREE.PerspectiveCamera(45, 16 / 9, 0.05, 100);
  private readonly target = new THREE.Vector3();
  /** Metres behind the body, to its right, and the camera height. */
  back = 3.0;
  side = 1.2;
  height = 1.6;

  constructor(private readonly container: HTMLElement) {}

  /**
   * Its renderer and canvas, made when first asked for (shown, drawn): a WebGL context is
   * 10–30 ms of main thread in software, and the page's first frame should not wait for one
   * that only a headset session shows.
   */
  get renderer(): THREE.WebGLRenderer {
    if (this.renderer_) return this.renderer_;
    const renderer = (this.renderer_ = new THREE.WebGLRenderer({ antialias: !softwareWebGL(), preserveDrawingBuffer: true }));
    rememberRenderer(renderer.getContext());
    renderer.outputColorSpace = THREE.SRGBColorSpace;
    renderer.domElement.id = 'spectator';
    this.container.appendChild(renderer.domElement);
    this.visible = false;
    return renderer;
  }

  get visible(): boolean {
    return !!this.renderer_ && !this.renderer_.domElement.hidden;
  }

  /** `hidden` alone does not hide it: three.js gives its canvas an inline `display: block`. */
  set visible(on: boolean) {
    if (!on && !this.renderer_) return;
    const canvas = this.renderer.domElement;
    if (on === this.visible && canvas.style.display) return;
    canvas.hidden = !on;
    canvas.style.display = on ? 'block' : 'none';
  }

  /** Draws `scene` looking at the avatar root (x, z) from behind its right shoulder, yaw `yaw`. */
  render(scene: THREE.Scene, x: number, z: number, yaw: number): void {
    const canvas = this.renderer.domElement;
    const w = canvas.clientWidth || 480;
    const h = canvas.clientHeight || 270;
    if (canvas.width !== w || canvas.height !== h) {
      this.renderer.setSize(w, h, false);
      this.camera.aspect = w / h;
      this.camera.updateProjectionMatrix();
    }
    // Behind the body and to its right (forward = (sin, 0, cos) of the yaw, right = (−cos, 0,
    // sin)), so the view stays over the shoulder as the user turns.
    const c = Math.cos(yaw), s = Math.sin(yaw);
    this.camera.position.set(x - this.back * s - this.side * c, this.height, z - this.back * c + this.side * s);
    this.target.set(x, 1.0, z);
    this.camera.lookAt(this.target);
    this.renderer.render(scene, this.camera);
  }
}
