/**
 * What motion matching is doing, drawn in the scene (Clavet 2016's debug views): the simulated
 * character the user steers and its predicted trajectory (orange), the trajectory of the frame
 * playing as stored in the database (cyan: how well the match fits the request), and the foot
 * locks (green rings where a toe is pinned). Everything is preallocated; `update` only writes
 * positions.
 */
import * as THREE from 'three';
import { overlayArrow, overlayLineMaterial, overlayMaterial } from './overlay-materials.ts';
import type { CharacterRuntime } from '../core/character.ts';

const REQUESTED = 0xff9a3c;
const MATCHED = 0x3cc8ff;
const LOCKED = 0x7dff8a;

/** Points with short facing strokes, on the floor. */
export class TrajectoryView {
  readonly object = new THREE.Group();
  private readonly dots: THREE.Mesh[] = [];
  private readonly strokes: THREE.LineSegments;
  private readonly strokePositions: Float32Array;
  private readonly line: THREE.Line;
  private readonly linePositions: Float32Array;

  constructor(count: number, color: number, y: number) {
    const material = overlayMaterial({ color, depthTest: false });
    const geometry = new THREE.SphereGeometry(0.035, 12, 8);
    for (let k = 0; k < count; k++) {
      const dot = new THREE.Mesh(geometry, material);
      dot.renderOrder = 10;
      this.dots.push(dot);
      this.object.add(dot);
    }
    const lineMaterial = overlayLineMaterial({ color, depthTest: false });
    this.strokePositions = new Float32Array(count * 6);
    const strokes = new THREE.BufferGeometry();
    strokes.setAttribute('position', new THREE.BufferAttribute(this.strokePositions, 3));
    this.strokes = new THREE.LineSegments(strokes, lineMaterial);
    this.linePositions = new Float32Array((count + 1) * 3);
    const line = new THREE.BufferGeometry();
    line.setAttribute('position', new THREE.BufferAttribute(this.linePositions, 3));
    this.line = new THREE.Line(line, lineMaterial);
    this.strokes.renderOrder = this.line.renderOrder = 10;
    this.strokes.frustumCulled = this.line.frustumCulled = false;
    this.object.add(this.strokes, this.line);
    this.object.position.y = y;
  }

  /** Point k at (x, z) facing (dx, dz); the line starts at (x0, z0). */
  set(k: number, x: number, z: number, dx: number, dz: number): void {
    this.dots[k].position.set(x, 0, z);
    const s = this.strokePositions;
    const len = Math.hypot(dx, dz) || 1;
    const o = k * 6;
    s[o] = x;
    s[o + 2] = z;
    s[o + 3] = x + (0.25 * dx) / len;
    s[o + 5] = z + (0.25 * dz) / len;
    this.start(x, z, k + 1);
  }

  /** Vertex `i` of the connecting line (0: where the trajectory starts). */
  start(x: number, z: number, i = 0): void {
    this.linePositions[i * 3] = x;
    this.linePositions[i * 3 + 2] = z;
  }

  commit(): void {
    this.strokes.geometry.attributes.position.needsUpdate = true;
    this.line.geometry.attributes.position.needsUpdate = true;
  }
}

export class DebugViews {
  readonly object = new THREE.Group();
  /** Each view on its own, for a settings panel. */
  readonly simulation = new THREE.Group();
  readonly requested: TrajectoryView;
  readonly matched: TrajectoryView;
  readonly locks = new THREE.Group();
  private readonly lockRings: THREE.Mesh[];

  /** Sized for `runtime`'s trajectories; `update` takes the runtime to draw (a restarted one keeps the views). */
  constructor(runtime: CharacterRuntime) {
    this.requested = new TrajectoryView(runtime.predictedPositions.length / 3, REQUESTED, 0.01);
    this.matched = new TrajectoryView(runtime.matchedTrajectory().length / 4, MATCHED, 0.012);

    const ring = new THREE.Mesh(new THREE.RingGeometry(0.16, 0.2, 32), overlayMaterial({ color: REQUESTED }));
    ring.rotation.x = -Math.PI / 2;
    const arrow = overlayArrow(new THREE.Vector3(0, 0, 1), 0.4, REQUESTED, 0.1, 0.07);
    this.simulation.add(ring, arrow);
    this.simulation.position.y = 0.008;

    const lockMaterial = overlayMaterial({ color: LOCKED, depthTest: false });
    this.lockRings = [0, 1].map(() => {
      const m = new THREE.Mesh(new THREE.RingGeometry(0.05, 0.07, 24), lockMaterial);
      m.rotation.x = -Math.PI / 2;
      m.renderOrder = 11;
      this.locks.add(m);
      return m;
    });
    this.object.add(this.simulation, this.requested.object, this.matched.object, this.locks);
  }

  /** Draws the runtime's state now (database units: put `object` where the character's pose is drawn). */
  update(runtime: CharacterRuntime): void {
    if (this.simulation.visible) {
      const s = runtime.simulation;
      this.simulation.position.set(s[0], 0.008, s[2]);
      this.simulation.quaternion.set(s[3], s[4], s[5], s[6]);
    }
    if (this.requested.object.visible) {
      const p = runtime.predictedPositions;
      const q = runtime.predictedRotations;
      const s = runtime.simulation;
      this.requested.start(s[0], s[2]);
      for (let k = 0; k < p.length / 3; k++) {
        // Facing = the yaw quaternion applied to +Z.
        const x = q[k * 4], y = q[k * 4 + 1], z = q[k * 4 + 2], w = q[k * 4 + 3];
        this.requested.set(k, p[k * 3], p[k * 3 + 2], 2 * (x * z + w * y), 1 - 2 * (x * x + y * y));
      }
      this.requested.commit();
    }
    if (this.matched.object.visible) {
      const m = runtime.matchedTrajectory();
      const root = runtime.root;
      this.matched.start(root[0], root[2]);
      for (let k = 0; k < m.length / 4; k++) this.matched.set(k, m[4 * k], m[4 * k + 1], m[4 * k + 2], m[4 * k + 3]);
      this.matched.commit();
    }
    if (this.locks.visible) {
      const locks = runtime.footLocks;
      const toes = runtime.toes;
      for (let side = 0; side < 2; side++) {
        const ring = this.lockRings[side];
        ring.visible = (locks & (1 << side)) !== 0;
        if (ring.visible) ring.position.set(toes[3 * side], 0.006, toes[3 * side + 2]);
      }
    }
  }

  dispose(): void {
    this.object.traverse((o) => {
      const m = o as THREE.Mesh;
      m.geometry?.dispose();
      (m.material as THREE.Material | undefined)?.dispose?.();
    });
  }
}
