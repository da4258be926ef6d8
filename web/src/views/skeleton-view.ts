/**
 * Draws a skeleton as spheres at the joints and lines to their parents. Geometry is allocated
 * once; `update()` writes positions in place. Joint 0 (the virtual root) is drawn by
 * `RootMarker` instead, so it has no sphere and no line to the hips.
 */
import * as THREE from 'three';
import { overlayLineMaterial } from './overlay-materials.ts';

const JOINT_RADIUS = 0.028;
const COLOR_JOINT = new THREE.Color(0xd8dde3);
const COLOR_CONTACT = new THREE.Color(0xff8a1f);
const COLOR_FOOT_FREE = new THREE.Color(0x5fa8ff);

const _m4 = new THREE.Matrix4();

export class SkeletonView {
  readonly object = new THREE.Group();
  private readonly joints: THREE.InstancedMesh;
  private readonly bones: THREE.LineSegments;
  private readonly linePositions: Float32Array;
  /** Pairs (child, parent) of drawn bones. */
  private readonly bonePairs: Int32Array;
  private readonly numJoints: number;
  private lastLeft = -1;
  private lastRight = -1;

  /**
   * @param parents parent index per joint (-1 for joint 0)
   * @param leftFoot joints colored by the left contact flag
   * @param rightFoot joints colored by the right contact flag
   */
  constructor(
    parents: Int32Array,
    private readonly leftFoot: readonly number[],
    private readonly rightFoot: readonly number[],
  ) {
    this.numJoints = parents.length;
    const sphere = new THREE.SphereGeometry(JOINT_RADIUS, 16, 10);
    const material = new THREE.MeshStandardMaterial({ roughness: 0.5, metalness: 0.0 });
    // Instance j-1 draws joint j.
    this.joints = new THREE.InstancedMesh(sphere, material, Math.max(1, this.numJoints - 1));
    this.joints.instanceMatrix.setUsage(THREE.DynamicDrawUsage);
    for (let j = 1; j < this.numJoints; j++) this.joints.setColorAt(j - 1, COLOR_JOINT);
    this.joints.frustumCulled = false;

    const pairs: number[] = [];
    for (let j = 1; j < this.numJoints; j++) if (parents[j] > 0) pairs.push(j, parents[j]);
    this.bonePairs = Int32Array.from(pairs);
    this.linePositions = new Float32Array(pairs.length * 3);
    const lineGeometry = new THREE.BufferGeometry();
    const attr = new THREE.BufferAttribute(this.linePositions, 3);
    attr.setUsage(THREE.DynamicDrawUsage);
    lineGeometry.setAttribute('position', attr);
    this.bones = new THREE.LineSegments(lineGeometry, overlayLineMaterial({ color: 0x9fb4c8 }));
    this.bones.frustumCulled = false;

    this.object.add(this.bones, this.joints);
  }

  /**
   * @param worldPositions `J×3` world positions of one frame
   * @param leftContact foot contact flag of the left foot in that frame
   * @param rightContact and of the right foot
   */
  update(worldPositions: Float32Array, leftContact: boolean, rightContact: boolean): void {
    for (let j = 1; j < this.numJoints; j++) {
      _m4.makeTranslation(worldPositions[j * 3], worldPositions[j * 3 + 1], worldPositions[j * 3 + 2]);
      this.joints.setMatrixAt(j - 1, _m4);
    }
    this.joints.instanceMatrix.needsUpdate = true;

    const pairs = this.bonePairs;
    const out = this.linePositions;
    for (let i = 0; i < pairs.length; i++) {
      const j = pairs[i];
      out[i * 3] = worldPositions[j * 3];
      out[i * 3 + 1] = worldPositions[j * 3 + 1];
      out[i * 3 + 2] = worldPositions[j * 3 + 2];
    }
    this.bones.geometry.attributes['position'].needsUpdate = true;

    const l = leftContact ? 1 : 0;
    const r = rightContact ? 1 : 0;
    if (l !== this.lastLeft || r !== this.lastRight) {
      for (const j of this.leftFoot) if (j > 0) this.joints.setColorAt(j - 1, l ? COLOR_CONTACT : COLOR_FOOT_FREE);
      for (const j of this.rightFoot) if (j > 0) this.joints.setColorAt(j - 1, r ? COLOR_CONTACT : COLOR_FOOT_FREE);
      if (this.joints.instanceColor) this.joints.instanceColor.needsUpdate = true;
      this.lastLeft = l;
      this.lastRight = r;
    }
  }
}
