/**
 * The joint-role vocabulary (`hips`, `left_toe`, `upper_chest`…), defined once in the runtime
 * (`wasm-core/src/runtime/roles.rs`) and shared by the database builder, the `.mmdb` site table and
 * avatars: `findRoles` runs the same name conventions and topology rules on an avatar's bones.
 */
import { find_roles_json, find_roles_rest_json, role_names_json } from './raw.ts';
import { asError } from './wasm.ts';

/** Every role in the runtime's order. */
export const ROLE_NAMES = [
  'hips',
  'left_upper_leg',
  'left_lower_leg',
  'left_foot',
  'left_toe',
  'right_upper_leg',
  'right_lower_leg',
  'right_foot',
  'right_toe',
  'spine',
  'chest',
  'upper_chest',
  'neck',
  'head',
  'left_shoulder',
  'left_upper_arm',
  'left_lower_arm',
  'left_hand',
  'right_shoulder',
  'right_upper_arm',
  'right_lower_arm',
  'right_hand',
] as const;

export type RoleName = (typeof ROLE_NAMES)[number];

/** Manual mapping, role → joint name (exact or normalized; '' unmaps the role). */
export type RoleOverrides = Readonly<Partial<Record<RoleName, string>>>;

/** The VRM humanoid bone name of each role (`left_toe` → `leftToes`), from the runtime. */
export function vrmBoneNames(): ReadonlyMap<RoleName, string> {
  const list = JSON.parse(role_names_json()) as { name: RoleName; vrm: string }[];
  if (list.length !== ROLE_NAMES.length || list.some((r, k) => r.name !== ROLE_NAMES[k])) {
    throw new Error('the role vocabulary of the WASM module differs from this library build');
  }
  return new Map(list.map((r) => [r.name, r.vrm]));
}

/**
 * The joint of each role in a skeleton of `names` with `parents` (−1 for roots), by the
 * runtime's rules (name conventions, hips from the legs). With `restPositions` (x, y, z per
 * joint in one model frame, any unit and facing) the skeleton's shape finds the roles the names
 * do not (limbs as pairs of matching branches, left from the pose): bones named `Bone.012` map
 * too. Throws on a bad override.
 */
export function findRoles(names: readonly string[], parents: ArrayLike<number>, overrides: RoleOverrides = {}, restPositions?: ArrayLike<number>): Map<RoleName, number> {
  let joints: Int32Array;
  try {
    joints = restPositions
      ? find_roles_rest_json(JSON.stringify(names), Int32Array.from(parents), Float32Array.from(restPositions), JSON.stringify(overrides))
      : find_roles_json(JSON.stringify(names), Int32Array.from(parents), JSON.stringify(overrides));
  } catch (e) {
    throw asError(e);
  }
  const roles = new Map<RoleName, number>();
  ROLE_NAMES.forEach((r, k) => {
    if (joints[k] >= 0) roles.set(r, joints[k]);
  });
  return roles;
}
