/**
 * Path mode: click the floor to place keypoints, each new segment at the current speed (Shift
 * held while clicking: the run speed), optionally looped; the character then follows the path
 * (`Character.followPath`). Drawn as a polyline with its keypoints; segments are tinted by speed.
 */
import * as THREE from 'three';

const WALK_COLOR = new THREE.Color(0xffd24a);
const RUN_COLOR = new THREE.Color(0xff5a4a);
const MAX_POINTS = 64;

export class PathEditor {
  readonly object = new THREE.Group();
  /** Keypoints, x and z interleaved. */
  readonly points: number[] = [];
  /** Speed (m/s) of each segment: segment i goes from point i to point i + 1 (the last back to 0 when looped). */
  readonly speeds: number[] = [];
  looped = true;
  /** Speed of segments added by a plain click, and by a Shift-click. */
  walkSpeed = 1.4;
  runSpeed = 3.5;
  /** Clicking the floor adds keypoints only while editing. */
  editing = false;
  /** Called before the first keypoint of a click (e.g. to start the path at the character). */
  onEditStart: () => void = () => {};
  /** Called after every change (add, clear, loop). */
  onChange: () => void = () => {};

  private readonly line: THREE.LineSegments;
  private readonly positions = new Float32Array(MAX_POINTS * 2 * 3);
  private readonly colors = new Float32Array(MAX_POINTS * 2 * 3);
  private readonly dots: THREE.InstancedMesh;
  private readonly raycaster = new THREE.Raycaster();
  private readonly floor = new THREE.Plane(new THREE.Vector3(0, 1, 0), 0);
  private readonly hit = new THREE.Vector3();
  private readonly ndc = new THREE.Vector2();
  private downAt = { x: 0, y: 0 };

  constructor(
    private readonly camera: THREE.Camera,
    private readonly dom: HTMLElement,
  ) {
    const geometry = new THREE.BufferGeometry();
    geometry.setAttribute('position', new THREE.BufferAttribute(this.positions, 3));
    geometry.setAttribute('color', new THREE.BufferAttribute(this.colors, 3));
    geometry.setDrawRange(0, 0);
    this.line = new THREE.LineSegments(geometry, new THREE.LineBasicMaterial({ vertexColors: true }));
    this.line.frustumCulled = false;
    this.dots = new THREE.InstancedMesh(new THREE.CylinderGeometry(0.06, 0.06, 0.02, 16), new THREE.MeshBasicMaterial({ color: 0xffd24a }), MAX_POINTS);
    this.dots.count = 0;
    this.dots.visible = false; // until there is a point: an instanced mesh is a shader program of its own
    this.dots.frustumCulled = false;
    this.object.add(this.line, this.dots);
    this.object.position.y = 0.015;
    // A click, not the end of an orbit drag: the pointer barely moved between down and up.
    dom.addEventListener('pointerdown', (e) => (this.downAt = { x: e.clientX, y: e.clientY }));
    dom.addEventListener('pointerup', (e) => {
      if (!this.editing || e.button !== 0) return;
      if (Math.hypot(e.clientX - this.downAt.x, e.clientY - this.downAt.y) > 4) return;
      const p = this.floorAt(e.clientX, e.clientY);
      if (!p) return;
      const [x, z] = [p.x, p.z];
      this.onEditStart();
      this.add(x, z, e.shiftKey ? this.runSpeed : this.walkSpeed);
    });
  }

  /** The floor point under client pixel (x, y), or null when looking above the horizon. */
  floorAt(clientX: number, clientY: number): THREE.Vector3 | null {
    const rect = this.dom.getBoundingClientRect();
    this.ndc.set(((clientX - rect.left) / rect.width) * 2 - 1, -((clientY - rect.top) / rect.height) * 2 + 1);
    this.raycaster.setFromCamera(this.ndc, this.camera);
    return this.raycaster.ray.intersectPlane(this.floor, this.hit);
  }

  /** Client pixel of floor point (x, z) (for tests and tools). */
  screenOf(x: number, z: number): { x: number; y: number } {
    const v = new THREE.Vector3(x, 0, z).project(this.camera);
    const rect = this.dom.getBoundingClientRect();
    return { x: rect.left + ((v.x + 1) / 2) * rect.width, y: rect.top + ((1 - v.y) / 2) * rect.height };
  }

  /** Adds a keypoint; `speed` is the speed of the segment arriving at it. */
  add(x: number, z: number, speed: number): void {
    if (this.points.length / 2 >= MAX_POINTS - 1) return;
    if (this.points.length >= 2) this.speeds.push(speed);
    this.points.push(x, z);
    this.redraw();
    this.onChange();
  }

  clear(): void {
    this.points.length = 0;
    this.speeds.length = 0;
    this.redraw();
    this.onChange();
  }

  /** Segment speeds as `Character.followPath` wants them (one more, closing the loop, when looped). */
  segmentSpeeds(): Float32Array {
    const s = [...this.speeds];
    if (this.looped) s.push(this.speeds.length ? this.speeds[this.speeds.length - 1] : this.walkSpeed);
    return Float32Array.from(s);
  }

  redraw(): void {
    const n = this.points.length / 2;
    const segments = this.looped && n > 2 ? n : n - 1;
    const p = this.points;
    let v = 0;
    for (let i = 0; i < Math.max(0, segments); i++) {
      const j = (i + 1) % n;
      const speed = i < this.speeds.length ? this.speeds[i] : (this.speeds[this.speeds.length - 1] ?? this.walkSpeed);
      const c = speed > (this.walkSpeed + this.runSpeed) / 2 ? RUN_COLOR : WALK_COLOR;
      for (const k of [i, j]) {
        this.positions.set([p[2 * k], 0, p[2 * k + 1]], v * 3);
        this.colors.set([c.r, c.g, c.b], v * 3);
        v++;
      }
    }
    this.line.geometry.setDrawRange(0, v);
    this.line.geometry.attributes.position.needsUpdate = true;
    this.line.geometry.attributes.color.needsUpdate = true;
    const m = new THREE.Matrix4();
    for (let k = 0; k < n; k++) this.dots.setMatrixAt(k, m.makeTranslation(p[2 * k], 0, p[2 * k + 1]));
    this.dots.count = n;
    this.dots.visible = n > 0;
    this.dots.instanceMatrix.needsUpdate = true;
  }
}
