/**
 * A skinned avatar (glTF/GLB) posed each frame from a database skeleton by T-pose retargeting
 * (THESIS_NOTES §8). The demo and the VR page both use it; `pose()` allocates nothing.
 */
import * as THREE from 'three';
import { type GLTF, GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { type VRM, VRMLoaderPlugin, VRMUtils } from '@pixiv/three-vrm';
import { type Crowd } from '../core/crowd.ts';
import { Grounding } from './grounding.ts';
import { findRoles, HUMANOID_ROLES, type HumanoidRole, type RoleOverrides } from './joint-maps.ts';
import { forwardKinematics as restKinematics, Retargeter } from './retarget.ts';

export interface Avatar {
  /** Add this to the scene. */
  readonly object: THREE.Object3D;
  /** The bones posed (of every skin, plus a VRM's humanoid bones), indexed like `roles`. */
  readonly bones: readonly THREE.Object3D[];
  /** Humanoid role → bone index. */
  readonly roles: ReadonlyMap<HumanoidRole, number>;
  /** Toe (ball) height standing on the floor (the rest pose), m; NaN without toes. */
  readonly standingToeHeight: number;
  /**
   * Room metres per source (database) unit horizontally, at object scale 1: the retargeter's
   * hips scale times the scale of whatever carries the root bones.
   */
  readonly hipsScale: number;
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

/**
 * The skeleton to retarget onto, read from the loaded three.js objects (so GLB and VRM, any
 * number of skins, and armature nodes above the root all work): every bone of every skinned
 * mesh (and a VRM's humanoid bones), each bone's parent being its nearest ancestor in that set.
 */
function skeletonOf(
  scene: THREE.Object3D,
  vrm: VRM | undefined,
  overrides: RoleOverrides | undefined,
): { bones: THREE.Object3D[]; parents: Int32Array; roles: Map<HumanoidRole, number> } {
  const set = new Set<THREE.Object3D>();
  scene.traverse((o) => {
    const m = o as THREE.SkinnedMesh;
    if (m.isSkinnedMesh) for (const b of m.skeleton.bones) set.add(b);
  });
  const vrmBones = new Map<HumanoidRole, THREE.Object3D>();
  if (vrm) {
    for (const role of HUMANOID_ROLES) {
      const node = vrm.humanoid.getRawBoneNode(role);
      if (node) {
        vrmBones.set(role, node);
        set.add(node);
      }
    }
  }
  const bones = [...set];
  const index = new Map(bones.map((b, i) => [b, i]));
  const parents = Int32Array.from(bones, (b) => {
    for (let p = b.parent; p; p = p.parent) if (index.has(p)) return index.get(p)!;
    return -1;
  });
  // A VRM says which bone is which; other models are matched by name conventions, with the
  // caller's overrides first.
  const roles = vrm && !overrides ? new Map([...vrmBones].map(([r, b]) => [r, index.get(b)!])) : findRoles(bones.map((b) => b.name), overrides);
  return { bones, parents, roles };
}

/**
 * Loads a GLB or VRM (bytes) and binds it to the crowd's skeleton. `name` is used in error
 * messages.
 */
export async function loadAvatar(bytes: Uint8Array, name: string, crowd: Crowd, overrides?: RoleOverrides): Promise<Avatar> {
  const loader = new GLTFLoader();
  loader.register((parser) => new VRMLoaderPlugin(parser));
  let gltf: GLTF;
  try {
    gltf = await loader.parseAsync(bytes.slice().buffer, '');
  } catch (e) {
    throw new Error(`${name}: not a glTF/GLB/VRM model (${e instanceof Error ? e.message : String(e)})`);
  }
  const vrm = gltf.userData.vrm as VRM | undefined;
  if (vrm) {
    // VRM 0.x faces −Z; and we pose the raw bones ourselves, so the normalized rig must not
    // overwrite them.
    VRMUtils.rotateVRM0(vrm);
    vrm.humanoid.autoUpdateHumanBones = false;
  }
  const root = vrm?.scene ?? gltf.scene;
  root.updateMatrixWorld(true);
  let skinned = 0;
  root.traverse((o) => {
    if ((o as THREE.SkinnedMesh).isSkinnedMesh) skinned++;
    // Skinned bounds stay at the rest pose's origin; the character walks away from it.
    o.frustumCulled = false;
    o.castShadow = true;
  });
  if (skinned === 0) throw new Error(`${name}: no skinned mesh`);
  let skeleton;
  try {
    skeleton = skeletonOf(root, vrm, overrides);
  } catch (e) {
    throw new Error(`${name}: ${e instanceof Error ? e.message : String(e)}`);
  }
  const { bones, parents, roles: targetRoles } = skeleton;
  if (!targetRoles.has('hips')) throw new Error(`${name}: no hips bone found among ${bones.length} bones (${bones.slice(0, 8).map((b) => b.name).join(', ')}, …)`);
  const restLocalRotations = new Float32Array(bones.length * 4);
  const restLocalPositions = new Float32Array(bones.length * 3);
  bones.forEach((b, i) => {
    b.quaternion.toArray(restLocalRotations, i * 4);
    b.position.toArray(restLocalPositions, i * 3);
  });
  // Whatever carries the root bones (an "Armature" node, a VRM 0 turn) rotates the whole rest pose.
  const hipsBone = bones[targetRoles.get('hips')!];
  let top = hipsBone;
  while (parents[bones.indexOf(top)] >= 0) top = bones[parents[bones.indexOf(top)]];
  const carrier = top.parent ? top.parent.getWorldQuaternion(new THREE.Quaternion()) : new THREE.Quaternion();

  // The .mmdb rest pose is the BVH rest: identity rotations, offsets = local positions.
  const j = crowd.numJoints;
  const sourceRest = new Float32Array(j * 4);
  for (let k = 0; k < j; k++) sourceRest[4 * k + 3] = 1;
  const sourceRestPositions = new Float64Array(j * 3);
  restKinematics(crowd.jointParents, sourceRest, crowd.positionsOf(0), new Float64Array(j * 4), sourceRestPositions);
  const sourceRoles = findRoles([...crowd.jointNames]);
  const retargeter = new Retargeter({
    sourceParents: crowd.jointParents,
    sourceRestWorldRotations: sourceRest,
    sourceRestWorldPositions: sourceRestPositions,
    targetParents: parents,
    targetRestLocalRotations: restLocalRotations,
    targetRestLocalPositions: restLocalPositions,
    targetRootParentRotation: carrier.toArray(),
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
  // Standing toe height in the world, read off the rest pose as loaded (any armature scale).
  const standing = toes.filter((t) => t !== undefined).map((t) => bones[t].getWorldPosition(toeWorld).y);
  const grounding = new Grounding(standing.length ? standing.reduce((a, b) => a + b) / standing.length : NaN);
  return {
    object: root,
    bones,
    roles: targetRoles,
    standingToeHeight: grounding.standingToeHeight,
    hipsScale: retargeter.hipsScale * (top.parent ? top.parent.getWorldScale(new THREE.Vector3()).x : 1),
    pose(world, worldRotations, contacts, dt, toeHeights) {
      hipsWorld[0] = world[3 * hips];
      hipsWorld[1] = world[3 * hips + 1] + grounding.offset / retargeter.hipsScale;
      hipsWorld[2] = world[3 * hips + 2];
      retargeter.apply(worldRotations, hipsWorld, local, hipsPosition);
      for (let b = 0; b < bones.length; b++) bones[b].quaternion.set(local[4 * b], local[4 * b + 1], local[4 * b + 2], local[4 * b + 3]);
      bones[targetHips].position.set(hipsPosition[0], hipsPosition[1], hipsPosition[2]);
      root.updateMatrixWorld(true);
      for (let side = 0; side < 2; side++) {
        const t = toes[side];
        toeHeights[side] = t === undefined ? NaN : bones[t].getWorldPosition(toeWorld).y;
      }
      grounding.update(toeHeights[0], toeHeights[1], contacts, dt);
    },
    dispose() {
      root.traverse((o) => {
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

/** Fetches and loads an avatar by URL. */
export async function fetchAvatar(url: string, crowd: Crowd): Promise<Avatar> {
  const response = await fetch(url);
  if (!response.ok) throw new Error(`${url}: HTTP ${response.status}`);
  return loadAvatar(new Uint8Array(await response.arrayBuffer()), url, crowd);
}
