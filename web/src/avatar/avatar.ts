/**
 * A skinned avatar (glTF/GLB) posed each frame from a database skeleton by T-pose retargeting
 * (THESIS_NOTES §8). The demo and the VR page both use it; `pose()` allocates nothing.
 */
import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { type Crowd } from '../core/crowd.ts';
import { type GlbSkeleton, skeletonFromGlb } from './glb-skeleton.ts';
import { Grounding } from './grounding.ts';
import { findRoles, type HumanoidRole } from './joint-maps.ts';
import { forwardKinematics as restKinematics, Retargeter } from './retarget.ts';

export interface Avatar {
  /** Add this to the scene. */
  readonly object: THREE.Object3D;
  /** The skin's bones, indexed like the glTF skin's joints (and `roles`). */
  readonly bones: readonly THREE.Bone[];
  /** Humanoid role → bone index. */
  readonly roles: ReadonlyMap<HumanoidRole, number>;
  /** Toe (ball) height standing on the floor (the rest pose), m; NaN without toes. */
  readonly standingToeHeight: number;
  /**
   * Poses the bones from the source skeleton's world joint positions (J×3) and rotations (J×4)
   * and its foot contacts (bits: 1 left, 2 right; they keep planted toes on the floor, see
   * `Grounding`), updates world matrices, and writes the toe (ball) heights above the floor
   * into `toeHeights` (NaN for a side without a toe bone).
   */
  pose(world: Float32Array, worldRotations: Float32Array, contacts: number, dt: number, toeHeights: [number, number]): void;
  /** Frees GPU resources; remove `object` from the scene first. */
  dispose(): void;
}

/** Loads a GLB (bytes) and binds it to the crowd's skeleton. `name` is used in error messages. */
export async function loadAvatar(bytes: Uint8Array, name: string, crowd: Crowd): Promise<Avatar> {
  const target = skeletonFromGlb(bytes);
  const gltf = await new GLTFLoader().parseAsync(bytes.slice().buffer, '');
  let mesh: THREE.SkinnedMesh | null = null;
  gltf.scene.traverse((o) => {
    if ((o as THREE.SkinnedMesh).isSkinnedMesh && !mesh) mesh = o as THREE.SkinnedMesh;
    // Skinned bounds stay at the rest pose's origin; the character walks away from it.
    o.frustumCulled = false;
    o.castShadow = true;
  });
  if (!mesh) throw new Error(`${name}: no skinned mesh`);
  const bones = (mesh as THREE.SkinnedMesh).skeleton.bones;
  // The .mmdb rest pose is the BVH rest: identity rotations, offsets = local positions.
  const j = crowd.numJoints;
  const sourceRest = new Float32Array(j * 4);
  for (let k = 0; k < j; k++) sourceRest[4 * k + 3] = 1;
  const sourceRestPositions = new Float64Array(j * 3);
  restKinematics(crowd.jointParents, sourceRest, crowd.positionsOf(0), new Float64Array(j * 4), sourceRestPositions);
  const sourceRoles = findRoles([...crowd.jointNames]);
  const targetRoles = findRoles(target.names);
  const retargeter = new Retargeter({
    sourceParents: crowd.jointParents,
    sourceRestWorldRotations: sourceRest,
    sourceRestWorldPositions: sourceRestPositions,
    targetParents: target.parents,
    targetRestLocalRotations: target.restLocalRotations,
    targetRestLocalPositions: target.restLocalPositions,
    sourceRoles,
    targetRoles,
    sourceToeHeight: crowd.toeHeight,
  });
  const hips = sourceRoles.get('hips') ?? 1;
  const targetHips = targetRoles.get('hips') ?? 0;
  const toes = [targetRoles.get('leftToes'), targetRoles.get('rightToes')];
  const local = new Float32Array(bones.length * 4);
  const hipsPosition = new Float32Array(3);
  const hipsWorld = new Float32Array(3);
  const toeWorld = new THREE.Vector3();
  const grounding = new Grounding(standingToeHeight(target, targetRoles));
  return {
    object: gltf.scene,
    bones,
    roles: targetRoles,
    standingToeHeight: grounding.standingToeHeight,
    pose(world, worldRotations, contacts, dt, toeHeights) {
      hipsWorld[0] = world[3 * hips];
      hipsWorld[1] = world[3 * hips + 1] + grounding.offset / retargeter.hipsScale;
      hipsWorld[2] = world[3 * hips + 2];
      retargeter.apply(worldRotations, hipsWorld, local, hipsPosition);
      for (let b = 0; b < bones.length; b++) bones[b].quaternion.set(local[4 * b], local[4 * b + 1], local[4 * b + 2], local[4 * b + 3]);
      bones[targetHips].position.set(hipsPosition[0], hipsPosition[1], hipsPosition[2]);
      gltf.scene.updateMatrixWorld(true);
      for (let side = 0; side < 2; side++) {
        const t = toes[side];
        toeHeights[side] = t === undefined ? NaN : bones[t].getWorldPosition(toeWorld).y;
      }
      grounding.update(toeHeights[0], toeHeights[1], contacts, dt);
    },
    dispose() {
      gltf.scene.traverse((o) => {
        const m = o as THREE.Mesh;
        if (!m.isMesh) return;
        m.geometry.dispose();
        for (const mat of Array.isArray(m.material) ? m.material : [m.material]) {
          for (const v of Object.values(mat)) if (v instanceof THREE.Texture) v.dispose();
          mat.dispose();
        }
      });
    },
  };
}

/** Mean rest (standing) height of the toe bones, or NaN without toes. */
function standingToeHeight(skeleton: GlbSkeleton, roles: ReadonlyMap<HumanoidRole, number>): number {
  const n = skeleton.parents.length;
  const positions = new Float64Array(n * 3);
  restKinematics(skeleton.parents, skeleton.restLocalRotations, skeleton.restLocalPositions, new Float64Array(n * 4), positions);
  const toes = [roles.get('leftToes'), roles.get('rightToes')].filter((t) => t !== undefined);
  return toes.reduce((sum, t) => sum + positions[t * 3 + 1], 0) / toes.length;
}

/** Fetches and loads an avatar by URL. */
export async function fetchAvatar(url: string, crowd: Crowd): Promise<Avatar> {
  const response = await fetch(url);
  if (!response.ok) throw new Error(`${url}: HTTP ${response.status}`);
  return loadAvatar(new Uint8Array(await response.arrayBuffer()), url, crowd);
}
