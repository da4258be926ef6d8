// Humanoid joint roles and the name conventions that map onto them (THESIS_NOTES §8).
//
// The canonical vocabulary is the VRM humanoid bone names. One table, `JOINT_NAME_TABLE`, lists
// for each role the joint name(s) used by each convention; `findRoles` matches a skeleton's
// joint names against it. Add a convention by adding a column, a role by adding a row.

/** Humanoid roles (VRM humanoid bone names), core body only: no fingers, eyes or jaw. */
export const HUMANOID_ROLES = [
  'hips',
  'spine',
  'chest',
  'upperChest',
  'neck',
  'head',
  'leftShoulder',
  'leftUpperArm',
  'leftLowerArm',
  'leftHand',
  'rightShoulder',
  'rightUpperArm',
  'rightLowerArm',
  'rightHand',
  'leftUpperLeg',
  'leftLowerLeg',
  'leftFoot',
  'leftToes',
  'rightUpperLeg',
  'rightLowerLeg',
  'rightFoot',
  'rightToes',
] as const;

export type HumanoidRole = (typeof HUMANOID_ROLES)[number];

/** The name conventions the table knows. */
export const CONVENTIONS = ['cmuAsf', 'cmuDaz', 'xsens', 'mixamo', 'unreal', 'vrm'] as const;
export type Convention = (typeof CONVENTIONS)[number];

/** One cell: a joint name, a list of alternatives (first found wins), or null (no such joint). */
type Cell = string | readonly string[] | null;

/**
 * Role → joint name per convention. Names are written as they appear in files; matching goes
 * through `normalizeJointName`, so case, separators and namespaces (`mixamorig:`) do not matter.
 *
 * - cmuAsf: CMU mocap ASF/AMC (and BVH converted from it), `root` is the hips.
 * - cmuDaz: the cgspeed "Daz-friendly" CMU BVH release.
 * - xsens: Xsens MVN segment names.
 * - mixamo: Mixamo rigs (`mixamorig:` prefix, stripped as a namespace); also the CMU
 *   "MotionBuilder-friendly" BVH names, which are the same.
 * - unreal: UE4/UE5 mannequin, Quaternius Universal Base Characters.
 * - vrm: VRM humanoid bone names, plus VRoid Studio's `J_Bip_*` node names.
 */
// prettier-ignore
export const JOINT_NAME_TABLE: Readonly<Record<HumanoidRole, Readonly<Record<Convention, Cell>>>> = {
  hips:          { cmuAsf: 'root',      cmuDaz: 'hip',      xsens: 'Pelvis',        mixamo: 'Hips',         unreal: 'pelvis',     vrm: ['hips', 'J_Bip_C_Hips'] },
  spine:         { cmuAsf: 'lowerback', cmuDaz: 'abdomen',  xsens: ['L3', 'L5'],    mixamo: 'Spine',        unreal: 'spine_01',   vrm: ['spine', 'J_Bip_C_Spine'] },
  chest:         { cmuAsf: 'upperback', cmuDaz: 'chest',    xsens: 'T12',           mixamo: 'Spine1',       unreal: 'spine_02',   vrm: ['chest', 'J_Bip_C_Chest'] },
  upperChest:    { cmuAsf: 'thorax',    cmuDaz: null,       xsens: 'T8',            mixamo: 'Spine2',       unreal: 'spine_03',   vrm: ['upperChest', 'J_Bip_C_UpperChest'] },
  neck:          { cmuAsf: 'lowerneck', cmuDaz: 'neck',     xsens: 'Neck',          mixamo: 'Neck',         unreal: 'neck_01',    vrm: ['neck', 'J_Bip_C_Neck'] },
  head:          { cmuAsf: 'head',      cmuDaz: 'head',     xsens: 'Head',          mixamo: 'Head',         unreal: 'head',       vrm: ['head', 'J_Bip_C_Head'] },
  leftShoulder:  { cmuAsf: 'lclavicle', cmuDaz: 'lCollar',  xsens: 'LeftShoulder',  mixamo: 'LeftShoulder', unreal: 'clavicle_l', vrm: ['leftShoulder', 'J_Bip_L_Shoulder'] },
  leftUpperArm:  { cmuAsf: 'lhumerus',  cmuDaz: 'lShldr',   xsens: 'LeftUpperArm',  mixamo: 'LeftArm',      unreal: 'upperarm_l', vrm: ['leftUpperArm', 'J_Bip_L_UpperArm'] },
  leftLowerArm:  { cmuAsf: 'lradius',   cmuDaz: 'lForeArm', xsens: 'LeftForeArm',   mixamo: 'LeftForeArm',  unreal: 'lowerarm_l', vrm: ['leftLowerArm', 'J_Bip_L_LowerArm'] },
  leftHand:      { cmuAsf: 'lwrist',    cmuDaz: 'lHand',    xsens: 'LeftHand',      mixamo: 'LeftHand',     unreal: 'hand_l',     vrm: ['leftHand', 'J_Bip_L_Hand'] },
  rightShoulder: { cmuAsf: 'rclavicle', cmuDaz: 'rCollar',  xsens: 'RightShoulder', mixamo: 'RightShoulder', unreal: 'clavicle_r', vrm: ['rightShoulder', 'J_Bip_R_Shoulder'] },
  rightUpperArm: { cmuAsf: 'rhumerus',  cmuDaz: 'rShldr',   xsens: 'RightUpperArm', mixamo: 'RightArm',     unreal: 'upperarm_r', vrm: ['rightUpperArm', 'J_Bip_R_UpperArm'] },
  rightLowerArm: { cmuAsf: 'rradius',   cmuDaz: 'rForeArm', xsens: 'RightForeArm',  mixamo: 'RightForeArm', unreal: 'lowerarm_r', vrm: ['rightLowerArm', 'J_Bip_R_LowerArm'] },
  rightHand:     { cmuAsf: 'rwrist',    cmuDaz: 'rHand',    xsens: 'RightHand',     mixamo: 'RightHand',    unreal: 'hand_r',     vrm: ['rightHand', 'J_Bip_R_Hand'] },
  leftUpperLeg:  { cmuAsf: 'lfemur',    cmuDaz: 'lThigh',   xsens: 'LeftUpperLeg',  mixamo: 'LeftUpLeg',    unreal: 'thigh_l',    vrm: ['leftUpperLeg', 'J_Bip_L_UpperLeg'] },
  leftLowerLeg:  { cmuAsf: 'ltibia',    cmuDaz: 'lShin',    xsens: 'LeftLowerLeg',  mixamo: 'LeftLeg',      unreal: 'calf_l',     vrm: ['leftLowerLeg', 'J_Bip_L_LowerLeg'] },
  leftFoot:      { cmuAsf: 'lfoot',     cmuDaz: 'lFoot',    xsens: 'LeftFoot',      mixamo: 'LeftFoot',     unreal: 'foot_l',     vrm: ['leftFoot', 'J_Bip_L_Foot'] },
  leftToes:      { cmuAsf: 'ltoes',     cmuDaz: null,       xsens: 'LeftToe',       mixamo: 'LeftToeBase',  unreal: 'ball_l',     vrm: ['leftToes', 'J_Bip_L_ToeBase'] },
  rightUpperLeg: { cmuAsf: 'rfemur',    cmuDaz: 'rThigh',   xsens: 'RightUpperLeg', mixamo: 'RightUpLeg',   unreal: 'thigh_r',    vrm: ['rightUpperLeg', 'J_Bip_R_UpperLeg'] },
  rightLowerLeg: { cmuAsf: 'rtibia',    cmuDaz: 'rShin',    xsens: 'RightLowerLeg', mixamo: 'RightLeg',     unreal: 'calf_r',     vrm: ['rightLowerLeg', 'J_Bip_R_LowerLeg'] },
  rightFoot:     { cmuAsf: 'rfoot',     cmuDaz: 'rFoot',    xsens: 'RightFoot',     mixamo: 'RightFoot',    unreal: 'foot_r',     vrm: ['rightFoot', 'J_Bip_R_Foot'] },
  rightToes:     { cmuAsf: 'rtoes',     cmuDaz: null,       xsens: 'RightToe',      mixamo: 'RightToeBase', unreal: 'ball_r',     vrm: ['rightToes', 'J_Bip_R_ToeBase'] },
};

/**
 * Normalizes a joint name for matching: drops a namespace (everything up to the last ':' or
 * '|', as in `mixamorig:LeftArm` or `Armature|Hips`), lowercases, keeps only [a-z0-9].
 */
export function normalizeJointName(name: string): string {
  const cut = Math.max(name.lastIndexOf(':'), name.lastIndexOf('|'));
  return name
    .slice(cut + 1)
    .toLowerCase()
    .replace(/[^a-z0-9]/g, '');
}

function cellNames(cell: Cell): readonly string[] {
  if (cell === null) return [];
  return typeof cell === 'string' ? [cell] : cell;
}

/**
 * Finds the joint index of each humanoid role in `names`.
 *
 * Conventions are tried best first (the one matching most roles), each filling only the roles
 * still missing with joints not used yet, so a skeleton that mixes conventions still maps.
 * `overrides` (role → joint name, exact or normalized) wins over the table; an override to ''
 * leaves that role unmapped. Throws when an override names a joint that is not in `names`.
 * Roles absent from the skeleton are absent from the result.
 */
/** Manual mapping, role → joint name (exact or normalized; '' unmaps the role). */
export type RoleOverrides = Readonly<Partial<Record<HumanoidRole | string, string>>>;

export function findRoles(names: readonly string[], overrides?: RoleOverrides): Map<HumanoidRole, number> {
  const byNorm = new Map<string, number>();
  names.forEach((n, i) => {
    const k = normalizeJointName(n);
    if (!byNorm.has(k)) byNorm.set(k, i);
  });
  const lookup = (cell: Cell): number => {
    for (const n of cellNames(cell)) {
      const i = byNorm.get(normalizeJointName(n));
      if (i !== undefined) return i;
    }
    return -1;
  };

  const result = new Map<HumanoidRole, number>();
  const used = new Set<number>();
  const fixed = new Set<HumanoidRole>();
  for (const [role, name] of Object.entries(overrides ?? {})) {
    if (!(HUMANOID_ROLES as readonly string[]).includes(role)) throw new Error(`joint override: unknown role "${role}"`);
    if (name === undefined) continue;
    fixed.add(role as HumanoidRole);
    if (name === '') continue;
    let i = names.indexOf(name);
    if (i < 0) i = byNorm.get(normalizeJointName(name)) ?? -1;
    if (i < 0) throw new Error(`joint override: ${role} → "${name}": no joint of that name`);
    result.set(role as HumanoidRole, i);
    used.add(i);
  }

  const ranked = CONVENTIONS.map((c) => ({
    c,
    score: HUMANOID_ROLES.reduce((s, r) => s + (lookup(JOINT_NAME_TABLE[r][c]) >= 0 ? 1 : 0), 0),
  }))
    .filter((x) => x.score > 0)
    .sort((a, b) => b.score - a.score); // stable: ties keep table order
  for (const { c } of ranked) {
    for (const role of HUMANOID_ROLES) {
      if (fixed.has(role) || result.has(role)) continue;
      const i = lookup(JOINT_NAME_TABLE[role][c]);
      if (i >= 0 && !used.has(i)) {
        result.set(role, i);
        used.add(i);
      }
    }
  }
  return result;
}
