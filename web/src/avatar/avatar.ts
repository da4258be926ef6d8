/**
 * A skinned avatar (glTF/GLB or VRM, or any three.js object with skinned meshes) posed each
 * frame from a character's world pose by the runtime's retargeting (docs/method.md §8): the
 * bones' local rotations and the hips translation are computed in WASM and copied into the
 * three.js bones here, then `Grounding` keeps planted feet on the floor. `pose()` allocates
 * nothing.
 */
import * as THREE from 'three';
import { type GLTF, GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { embeddedImages } from './embedded-images.ts';
import { MeshoptDecoder } from 'three/addons/libs/meshopt_decoder.module.js';
import { clone as cloneSkinned } from 'three/addons/utils/SkeletonUtils.js';
import type { VRM } from '@pixiv/three-vrm';
import type { CharacterRuntime } from '../core/character.ts';
import type { Database } from '../core/database.ts';
import { Retargeter } from '../core/retarget.ts';
import { initWasm } from '../core/wasm.ts';
import { findRoles, ROLE_NAMES, type RoleName, type RoleOverrides, vrmBoneNames } from '../core/roles.ts';
import { type FetchOptions, fetchBytes, mark } from '../fetch.ts';
import { cullHiddenBackFaces } from './closed-mesh.ts';
import { attachRigidMeshes } from './rigid-meshes.ts';
import { declaresVrm } from './vrm-file.ts';
import { Grounding } from './grounding.ts';

export interface AvatarOptions {
  /** Manual joint map (role → bone name) over the name conventions (and over a VRM's own map). */
  roles?: RoleOverrides;
  /** Name used in messages (defaults to the URL). */
  name?: string;
}

const _v = new THREE.Vector3();
const _m = new THREE.Matrix4();

/** The bones to retarget onto: every bone of every skinned mesh (and a VRM's humanoid bones). */
function skeletonOf(root: THREE.Object3D, vrm: VRM | undefined): THREE.Object3D[] {
  const set = new Set<THREE.Object3D>();
  root.traverse((o) => {
    const m = o as THREE.SkinnedMesh;
    if (m.isSkinnedMesh) for (const b of m.skeleton.bones) set.add(b);
  });
  if (vrm) {
    for (const vrmName of vrmBoneNames().values()) {
      const node = vrm.humanoid.getRawBoneNode(vrmName as Parameters<VRM['humanoid']['getRawBoneNode']>[0]);
      if (node) set.add(node);
    }
  }
  return [...set];
}

export class Avatar {
  /** Add this to a scene (the character's `object3d` holds it). */
  readonly object: THREE.Object3D;
  readonly name: string;
  /** The bones posed, indexed like `parents` and `roles`. */
  readonly bones: readonly THREE.Object3D[];
  /** Parent of each bone among `bones` (its nearest ancestor in the set), −1 for none. */
  readonly parents: Int32Array;
  readonly roles: ReadonlyMap<RoleName, number>;
  /**
   * A VRM model's `VRM` object from `@pixiv/three-vrm` (undefined for a plain glTF): cast it to
   * use it as one (`avatar.vrm as VRM`). Typed by its shape so that the package's types never
   * load three-vrm's, which do not resolve under TypeScript's `moduleResolution: node16`.
   */
  readonly vrm: { readonly scene: THREE.Object3D; readonly meta: unknown; update(delta: number): void } | undefined;
  /** Toe height standing on the floor (the rest pose), avatar units; NaN without toes. */
  readonly standingToeHeight: number;
  /** Toe heights after the last `pose` (left, right), avatar units; NaN for a missing toe. */
  readonly toeHeights: [number, number] = [NaN, NaN];
  private readonly restRotations: Float32Array;
  private readonly restPositions: Float32Array;
  private readonly rootParentRotation: THREE.Quaternion;
  /** Scale of whatever carries the root bones (an "Armature" in centimetres…). */
  private readonly carrierScale: number;
  private readonly grounding: Grounding;
  private readonly toes: (number | undefined)[];
  private retargeter: Retargeter | null = null;
  /** The core poses the bones' and skins' matrices (`coreSkinning`): the skins and the root bones' carrier. */
  private core: { skeletons: THREE.Skeleton[]; carrier: THREE.Object3D } | null = null;
  /** Avatars sharing these geometries, materials and textures (`clone`): the last one disposed frees them. */
  private readonly assets: { users: number };
  private disposed = false;

  private constructor(
    root: THREE.Object3D,
    name: string,
    vrm: VRM | undefined,
    private readonly overrides: RoleOverrides | undefined,
    assets = { users: 1 },
  ) {
    this.assets = assets;
    this.object = root;
    this.name = name;
    this.vrm = vrm;
    root.updateMatrixWorld(true);
    let skinned = 0;
    root.traverse((o) => {
      const mesh = o as THREE.SkinnedMesh;
      if (mesh.isSkinnedMesh) {
        skinned++;
        // Bounds of the rest pose, from the geometry (a glTF's accessor min/max): left unset,
        // three.js skins every vertex on the CPU in the first frame to find them (12-18 ms for
        // the shipped avatar) only to sort by them — culling is off, and the bounds would be
        // stale as soon as the character moves anyway.
        if (!mesh.geometry.boundingSphere) mesh.geometry.computeBoundingSphere();
        mesh.boundingSphere ??= mesh.geometry.boundingSphere!.clone();
      }
      // Skinned bounds stay at the rest pose's origin; the character walks away from it.
      o.frustumCulled = false;
      o.castShadow = true;
    });
    if (skinned === 0) throw new Error(`${name}: no skinned mesh`);
    const bones = skeletonOf(root, vrm);
    const index = new Map(bones.map((b, i) => [b, i]));
    this.bones = bones;
    this.parents = Int32Array.from(bones, (b) => {
      for (let p = b.parent; p; p = p.parent) if (index.has(p)) return index.get(p)!;
      return -1;
    });
    // A VRM says which bone is which; other models go by the runtime's name conventions, and
    // where the names say nothing, by the skeleton's shape in its rest pose (the model frame).
    if (vrm && !overrides) {
      const roles = new Map<RoleName, number>();
      for (const [role, vrmName] of vrmBoneNames()) {
        const node = vrm.humanoid.getRawBoneNode(vrmName as Parameters<VRM['humanoid']['getRawBoneNode']>[0]);
        if (node && index.has(node)) roles.set(role, index.get(node)!);
      }
      this.roles = roles;
    } else {
      try {
        const toModel = root.matrixWorld.clone().invert(); // world matrices updated above
        const at = new THREE.Vector3();
        const rest = bones.flatMap((b) => at.setFromMatrixPosition(b.matrixWorld).applyMatrix4(toModel).toArray());
        this.roles = findRoles(bones.map((b) => b.name), this.parents, overrides, rest);
      } catch (e) {
        throw new Error(`${name}: ${e instanceof Error ? e.message : String(e)}`);
      }
    }
    if (!this.roles.has('hips')) throw new Error(`${name}: no hips bone found among ${bones.length} bones (${bones.slice(0, 8).map((b) => b.name).join(', ')}, …)`);
    this.restRotations = new Float32Array(bones.length * 4);
    this.restPositions = new Float32Array(bones.length * 3);
    bones.forEach((b, i) => {
      b.quaternion.toArray(this.restRotations, i * 4);
      b.position.toArray(this.restPositions, i * 3);
    });
    // Whatever carries the root bones (an "Armature" node, a VRM 0 turn) turns and scales the rest pose.
    const carrier = bones[this.rootBone()].parent;
    this.rootParentRotation = carrier ? carrier.getWorldQuaternion(new THREE.Quaternion()) : new THREE.Quaternion();
    this.carrierScale = carrier ? carrier.getWorldScale(new THREE.Vector3()).x / root.getWorldScale(new THREE.Vector3()).x : 1;
    this.toes = [this.roles.get('left_toe'), this.roles.get('right_toe')];
    const standing = this.toes.filter((t) => t !== undefined).map((t) => this.heightOf(bones[t]));
    this.grounding = new Grounding(standing.length ? standing.reduce((a, b) => a + b) / standing.length : NaN);
    this.standingToeHeight = this.grounding.standingToeHeight;
  }

  /**
   * Height of a bone above the avatar object's floor (its parent's frame, avatar units), from the
   * world matrices as last updated (`pose` and the constructor update them first): the parent's
   * own world matrix cancels out, so a stale one does not matter — and its ancestors are not
   * walked again (`getWorldPosition` recomputed ~10 matrices per toe, every character, every frame).
   */
  private heightOf(bone: THREE.Object3D): number {
    _v.setFromMatrixPosition(bone.matrixWorld);
    if (this.object.parent) _v.applyMatrix4(_m.copy(this.object.parent.matrixWorld).invert());
    return _v.y;
  }

  /**
   * Loads a GLB/VRM (URL or bytes) or wraps a three.js object that has skinned meshes. Throws
   * an Error naming the source: not a model, no skinned mesh, no hips.
   */
  static async load(source: string | URL | Uint8Array | THREE.Object3D, options: AvatarOptions & FetchOptions = {}): Promise<Avatar> {
    // Finding the roles runs in the core: it loads in parallel with the file and its parse.
    const core = initWasm(undefined, options);
    core.catch(() => undefined); // awaited below; not an unhandled rejection if the file fails first
    if (source instanceof THREE.Object3D) return (await core, new Avatar(source, options.name ?? source.name ?? 'avatar', undefined, options.roles));
    const name = options.name ?? (source instanceof Uint8Array ? 'avatar' : String(source));
    const bytes = source instanceof Uint8Array ? source : await fetchBytes(source, { stage: 'avatar', ...options });
    const loader = new GLTFLoader();
    // The shipped avatar is meshopt-compressed with WebP textures (scripts/compress-avatar.mjs);
    // the decoder runs on this thread (no worker: CSP-safe, 'wasm-unsafe-eval' only). Any other
    // GLB/VRM loads as it is.
    loader.setMeshoptDecoder(MeshoptDecoder);
    loader.register(embeddedImages);
    // three-vrm is fetched only for a file that is a VRM (vrm-file.ts).
    const vrmLib = declaresVrm(bytes) ? await import('@pixiv/three-vrm') : null;
    if (vrmLib) loader.register((parser) => new vrmLib.VRMLoaderPlugin(parser));
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
      vrmLib?.VRMUtils.rotateVRM0(vrm);
      vrm.humanoid.autoUpdateHumanBones = false;
    }
    // A loaded file's meshes are ours to reshape: a mesh following one bone rigidly rides it
    // (rigid-meshes.ts: one skeleton upload a frame per avatar, not one per mesh). Not for a VRM,
    // whose extras (look-at, first-person layers) address its meshes.
    if (!vrm) attachRigidMeshes(gltf.scene);
    // The parse (meshopt, images) went on while the core compiled; only finding the roles needs it.
    await core;
    const avatar = new Avatar(vrm?.scene ?? gltf.scene, name, vrm, options.roles);
    cullHiddenBackFaces(avatar.object); // a loaded file's materials are ours to set (closed-mesh.ts)
    mark('mm:avatar-ready');
    return avatar;
  }

  /**
   * Binds the avatar to a database's skeleton (the retargeting is built once per database).
   * Returns avatar metres per database metre horizontally (the character's world scale).
   */
  bind(database: Database): number {
    this.retargeter?.free();
    this.retargeter = null;
    this.retargeter = new Retargeter(database, {
      parents: this.parents,
      restRotations: this.restRotations,
      restPositions: this.restPositions,
      roles: this.roles,
      rootParentRotation: this.rootParentRotation.toArray(),
    });
    this.grounding.offset = 0;
    if (this.core) this.enableCoreSkinning(this.retargeter, this.core.skeletons);
    return this.retargeter.hipsScale * this.carrierScale;
  }

  /**
   * Whether the core computes the bones' world matrices and the skins' matrices (one FK pass
   * in WASM, runtime/skinning.rs) instead of three.js (`updateMatrixWorld` over every bone, then
   * `Skeleton.update`): for many avatars at once — the crowd page sets it. The bones' world
   * matrices are written each `pose` (read them as usual), their `position` and `quaternion`
   * are not, so code that edits bones after `pose` (the VR page's upper body) keeps the
   * default (false). Models it cannot take (a VRM, bones with a scale, bones under a node that
   * is not a bone, skins with bones of their own) stay with three.js: reading it back says so.
   */
  get coreSkinning(): boolean {
    return this.core !== null;
  }

  set coreSkinning(on: boolean) {
    if (on === (this.core !== null)) return;
    const skeletons = new Set<THREE.Skeleton>();
    this.object.traverse((o) => (o as THREE.SkinnedMesh).isSkinnedMesh && skeletons.add((o as THREE.SkinnedMesh).skeleton));
    if (!on) {
      for (const k of skeletons) delete (k as { update?: unknown }).update; // three.js' own again
      for (const b of this.bones) b.matrixAutoUpdate = b.matrixWorldAutoUpdate = true;
      this.core = null;
      return;
    }
    const index = new Set<THREE.Object3D>(this.bones);
    const carrier = this.bones[this.rootBone()].parent;
    const fits =
      !this.vrm &&
      carrier !== null &&
      this.bones.every((b, i) => (this.parents[i] >= 0 ? index.has(b.parent!) : b.parent === carrier)) &&
      this.bones.every((b) => Math.abs(b.scale.x - 1) + Math.abs(b.scale.y - 1) + Math.abs(b.scale.z - 1) < 1e-4) &&
      [...skeletons].every((k) => k.bones.every((b) => index.has(b)));
    if (!fits) return;
    this.core = { skeletons: [...skeletons], carrier };
    if (this.retargeter) this.enableCoreSkinning(this.retargeter, this.core.skeletons);
    for (const b of this.bones) b.matrixAutoUpdate = b.matrixWorldAutoUpdate = false;
    // The renderer calls `update` once a frame per skeleton: the matrices are already in place.
    for (const k of skeletons) k.update = () => void (k.boneTexture && (k.boneTexture.needsUpdate = true));
  }

  private enableCoreSkinning(r: Retargeter, skeletons: THREE.Skeleton[]): void {
    const bone = new Map(this.bones.map((b, i) => [b as THREE.Object3D, i]));
    const skins = skeletons.map((k) => ({ bones: k.bones.map((b) => bone.get(b)!), inverseBinds: k.boneInverses.flatMap((m) => m.elements) }));
    r.enableSkinning({ parents: this.parents, restPositions: this.restPositions }, skins);
  }

  /** The topmost bone above the hips (whose parent carries the skeleton). */
  private rootBone(): number {
    let top = this.roles.get('hips')!;
    while (this.parents[top] >= 0) top = this.parents[top];
    return top;
  }

  /** Puts every bone back in its rest pose (until the next `pose`), matrices updated. */
  resetToRest(): void {
    const core = this.coreSkinning; // three.js' pass computes the rest matrices
    this.coreSkinning = false;
    this.bones.forEach((b, i) => {
      b.quaternion.fromArray(this.restRotations, i * 4);
      b.position.fromArray(this.restPositions, i * 3);
    });
    this.object.updateMatrixWorld(true);
    this.coreSkinning = core;
  }

  /** The bone of a role, if the avatar has it. */
  bone(role: RoleName): THREE.Object3D | undefined {
    const i = this.roles.get(role);
    return i === undefined ? undefined : this.bones[i];
  }

  /**
   * Poses the bones from `runtime`'s world pose (bound database), updates world matrices and
   * the grounding (feet in contact on the floor; `dt` seconds).
   */
  pose(runtime: CharacterRuntime, dt: number): void {
    const r = this.retargeter;
    if (!r) throw new Error(`${this.name}: pose() before bind()`);
    r.apply(runtime, this.grounding.offset / this.carrierScale);
    const bones = this.bones;
    if (this.core) {
      // The core's FK: world matrices straight into the bones, skin matrices into the skeletons.
      this.core.carrier.updateWorldMatrix(true, false);
      r.skin(this.core.carrier.matrixWorld.elements);
      const w = r.worldMatrices;
      for (let b = 0; b < bones.length; b++) {
        const e = bones[b].matrixWorld.elements;
        for (let k = 0; k < 16; k++) e[k] = w[16 * b + k];
      }
      const skeletons = this.core.skeletons;
      for (let s = 0; s < skeletons.length; s++) skeletons[s].boneMatrices!.set(r.skinMatrices(s));
    } else {
      const q = r.localRotations;
      for (let b = 0; b < bones.length; b++) bones[b].quaternion.set(q[4 * b], q[4 * b + 1], q[4 * b + 2], q[4 * b + 3]);
      const h = r.hipsPosition;
      bones[r.targetHips].position.set(h[0], h[1], h[2]);
      this.object.updateMatrixWorld(true);
    }
    for (let side = 0; side < 2; side++) {
      const t = this.toes[side];
      this.toeHeights[side] = t === undefined ? NaN : this.heightOf(bones[t]);
    }
    this.grounding.update(this.toeHeights[0], this.toeHeights[1], runtime.contacts, dt);
  }

  /** Whether this avatar or one sharing its resources (`clone`) is not disposed yet. @internal */
  get inUse(): boolean {
    return this.assets.users > 0;
  }

  /**
   * A second avatar of the same model, at rest, sharing this one's geometries, materials and
   * textures: nothing is downloaded, parsed, uploaded or compiled again (a shared room shows
   * several people with the page's own avatar; on a software GPU each new material is a shader
   * compile of a second or more). The shared resources are freed with the last of them. Not for
   * VRM models (their extras need a load of their own: use `Avatar.load`).
   */
  clone(): Avatar {
    if (this.vrm) throw new Error(`${this.name}: a VRM model is not cloned; load it again`);
    // Cloned from three.js' own posing (the core's leaves the bones' local transforms behind).
    const core = this.coreSkinning;
    this.coreSkinning = false;
    const posed = this.bones.map((b) => [b.position.clone(), b.quaternion.clone()] as const);
    this.resetToRest();
    let copy: Avatar;
    try {
      copy = new Avatar(cloneSkinned(this.object), this.name, undefined, this.overrides, this.assets);
    } finally {
      this.bones.forEach((b, i) => (b.position.copy(posed[i][0]), b.quaternion.copy(posed[i][1])));
      this.object.updateMatrixWorld(true);
      this.coreSkinning = core;
    }
    this.assets.users++;
    return copy;
  }

  /** Frees the retargeting and GPU resources (shared ones with the last `clone`); remove `object` from its scene first. */
  dispose(): void {
    this.retargeter?.free();
    this.retargeter = null;
    if (this.disposed) return;
    this.disposed = true;
    if (--this.assets.users > 0) return;
    this.object.traverse((o) => {
      const m = o as THREE.Mesh;
      if (!m.isMesh) return;
      m.geometry.dispose();
      for (const mat of Array.isArray(m.material) ? m.material : [m.material]) {
        for (const v of Object.values(mat)) if (v instanceof THREE.Texture) v.dispose();
        mat.dispose();
      }
    });
  }
}

export { ROLE_NAMES };
