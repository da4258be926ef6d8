//! The one joint-role vocabulary of the product: which joint of a skeleton is the hips, the left
//! foot, the head… It is shared by the database builder (BVH skeletons), the `.mmdb` site table
//! (a database's roles, by [`Role::name`]) and avatars (GLB/VRM skeletons, through the bindings),
//! so every part of the engine means the same thing by "left foot".
//!
//! Roles are found by joint name across the conventions in the wild (CMU ASF and its Daz-,
//! MotionBuilder- and 3dsMax-friendly BVH releases, Xsens MVN, 100STYLE, Mixamo, Unreal /
//! Quaternius, VRM humanoid and VRoid `J_Bip_*`), with the hips found from the topology (the
//! common ancestor of the two legs). Names are compared normalized: namespace dropped
//! (`mixamorig:`), lowercase, alphanumerics only.

use glam::DVec3;
use std::collections::HashMap;

/// A body part. Snake-case names ([`Role::name`]) are the vocabulary's spelling everywhere
/// (`.mmdb` sites, build configs, the TS API); [`Role::vrm_name`] is the VRM humanoid bone.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Role {
    Hips,
    LeftUpperLeg,
    LeftLowerLeg,
    LeftFoot,
    LeftToe,
    RightUpperLeg,
    RightLowerLeg,
    RightFoot,
    RightToe,
    Spine,
    Chest,
    UpperChest,
    Neck,
    Head,
    LeftShoulder,
    LeftUpperArm,
    LeftLowerArm,
    LeftHand,
    RightShoulder,
    RightUpperArm,
    RightLowerArm,
    RightHand,
}

/// Number of roles.
pub const NUM_ROLES: usize = 22;

impl Role {
    /// Every role, in the `.mmdb` site-table order.
    pub const ALL: [Role; NUM_ROLES] = [
        Role::Hips,
        Role::LeftUpperLeg,
        Role::LeftLowerLeg,
        Role::LeftFoot,
        Role::LeftToe,
        Role::RightUpperLeg,
        Role::RightLowerLeg,
        Role::RightFoot,
        Role::RightToe,
        Role::Spine,
        Role::Chest,
        Role::UpperChest,
        Role::Neck,
        Role::Head,
        Role::LeftShoulder,
        Role::LeftUpperArm,
        Role::LeftLowerArm,
        Role::LeftHand,
        Role::RightShoulder,
        Role::RightUpperArm,
        Role::RightLowerArm,
        Role::RightHand,
    ];

    /// The role's name in the vocabulary: `hips`, `left_upper_leg`, `left_toe`, `upper_chest`…
    pub fn name(self) -> &'static str {
        NAMES[self as usize].0
    }

    /// The VRM humanoid bone name of the role (`leftUpperLeg`, `leftToes`…).
    pub fn vrm_name(self) -> &'static str {
        NAMES[self as usize].1
    }

    /// The role named `name` (vocabulary spelling).
    pub fn from_name(name: &str) -> Option<Role> {
        Role::ALL.into_iter().find(|r| r.name() == name)
    }

    /// Index of the role in [`Role::ALL`].
    pub fn index(self) -> usize {
        self as usize
    }

    /// The same part on the other side (`LeftFoot` ↔ `RightFoot`); centre roles map to themselves.
    pub fn mirror(self) -> Role {
        let name = self.name();
        let other = if let Some(rest) = name.strip_prefix("left_") {
            format!("right_{rest}")
        } else if let Some(rest) = name.strip_prefix("right_") {
            format!("left_{rest}")
        } else {
            return self;
        };
        Role::from_name(&other).unwrap_or(self)
    }

    /// `(side letter, side word)` for a sided role: `("l", "left")`, `("r", "right")`.
    fn side(self) -> Option<(&'static str, &'static str)> {
        let name = self.name();
        if name.starts_with("left_") {
            Some(("l", "left"))
        } else if name.starts_with("right_") {
            Some(("r", "right"))
        } else {
            None
        }
    }
}

const NAMES: [(&str, &str); NUM_ROLES] = [
    ("hips", "hips"),
    ("left_upper_leg", "leftUpperLeg"),
    ("left_lower_leg", "leftLowerLeg"),
    ("left_foot", "leftFoot"),
    ("left_toe", "leftToes"),
    ("right_upper_leg", "rightUpperLeg"),
    ("right_lower_leg", "rightLowerLeg"),
    ("right_foot", "rightFoot"),
    ("right_toe", "rightToes"),
    ("spine", "spine"),
    ("chest", "chest"),
    ("upper_chest", "upperChest"),
    ("neck", "neck"),
    ("head", "head"),
    ("left_shoulder", "leftShoulder"),
    ("left_upper_arm", "leftUpperArm"),
    ("left_lower_arm", "leftLowerArm"),
    ("left_hand", "leftHand"),
    ("right_shoulder", "rightShoulder"),
    ("right_upper_arm", "rightUpperArm"),
    ("right_lower_arm", "rightLowerArm"),
    ("right_hand", "rightHand"),
];

/// Candidate joint names per role, normalized (see [`normalize_name`]), best first: the first
/// candidate present (and not taken by an earlier role) wins. Sided roles are templates: `{s}`
/// is the side letter (`l`/`r`), `{side}` the word (`left`/`right`). Order matters where
/// conventions disagree: CMU Daz's `lShldr` is an upper arm, Xsens' and Mixamo's `LeftShoulder`
/// a clavicle, 100STYLE's `LeftShoulder` an upper arm (its clavicle is `LeftCollar`), so the
/// clavicle names that are never ambiguous come first and a joint takes one role only.
fn candidates(role: Role) -> &'static [&'static str] {
    use Role::*;
    match role {
        // Hips: found from the legs (see `find_roles`); names are the fallback.
        Hips => &["hips", "hip", "pelvis", "root", "jbipchips"],
        // CMU ASF, Daz, Mixamo/VRM, Unreal, Xsens, VRoid, 100STYLE (its first spine joint is `Chest`).
        Spine => &["lowerback", "abdomen", "spine", "spine01", "l5", "l3", "jbipcspine", "chest"],
        Chest => &["upperback", "chest", "spine1", "spine02", "t12", "jbipcchest", "chest2"],
        UpperChest => &["thorax", "upperchest", "spine2", "spine03", "t8", "jbipcupperchest", "chest3", "chest4"],
        Neck => &["lowerneck", "neck", "neck01", "neck1", "jbipcneck"],
        Head => &["head", "jbipchead"],
        LeftUpperLeg | RightUpperLeg => &[
            "{s}femur",
            "{s}thigh",
            "{side}upperleg",
            "{side}upleg",
            "thigh{s}",
            "{side}thigh",
            "{s}upleg",
            "jbip{s}upperleg",
            "{side}hip",
        ],
        LeftLowerLeg | RightLowerLeg => &[
            "{s}tibia",
            "{s}shin",
            "{side}lowerleg",
            "{side}leg",
            "calf{s}",
            "{side}shin",
            "{s}leg",
            "jbip{s}lowerleg",
            "{side}knee",
        ],
        LeftFoot | RightFoot => &["{s}foot", "{side}foot", "foot{s}", "jbip{s}foot", "{side}ankle", "{s}ankle"],
        LeftToe | RightToe => &[
            "{s}toes",
            "{s}toe",
            "{side}toe",
            "{side}toebase",
            "{side}toes",
            "ball{s}",
            "toe{s}",
            "toes{s}",
            "{side}toe0",
            "jbip{s}toebase",
        ],
        LeftShoulder | RightShoulder => &[
            "{s}clavicle",
            "{s}collar",
            "{side}collar",
            "{side}clavicle",
            "clavicle{s}",
            "jbip{s}shoulder",
            "{side}shoulder",
        ],
        LeftUpperArm | RightUpperArm => &[
            "{s}humerus",
            "{s}shldr",
            "{side}upperarm",
            "{side}arm",
            "upperarm{s}",
            "jbip{s}upperarm",
            "{side}shoulder",
            "{s}shoulder",
        ],
        LeftLowerArm | RightLowerArm => &[
            "{s}radius",
            "{s}forearm",
            "{side}forearm",
            "{side}lowerarm",
            "lowerarm{s}",
            "jbip{s}lowerarm",
            "{side}elbow",
        ],
        LeftHand | RightHand => &["{s}wrist", "{s}hand", "{side}hand", "hand{s}", "jbip{s}hand", "{side}wrist"],
    }
}

/// Lowercase alphanumerics of a joint name without its namespace (`mixamorig:LeftFoot` →
/// `leftfoot`, `Armature|thigh_L` → `thighl`).
pub fn normalize_name(name: &str) -> String {
    let base = name.rsplit([':', '|']).next().unwrap_or(name);
    base.chars().filter(|c| c.is_ascii_alphanumeric()).map(|c| c.to_ascii_lowercase()).collect()
}

/// The joint playing each role in one skeleton, or `None`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Roles([Option<usize>; NUM_ROLES]);

/// Limb bones as (joint role, child role): the bones whose rest directions retargeting aligns,
/// at build time (`builder/retarget.rs`) and onto an avatar (`retarget.rs`). A role without a
/// child joint (a foot without a toe) uses its end site. Not the clavicles: anatomy differs there
/// (CMU's clavicle rises ~20° to the shoulder, a game avatar's is level), and copying its
/// direction shrugs the shoulders.
pub const LIMB_BONES: [(Role, Role); 10] = [
    (Role::LeftUpperArm, Role::LeftLowerArm),
    (Role::LeftLowerArm, Role::LeftHand),
    (Role::RightUpperArm, Role::RightLowerArm),
    (Role::RightLowerArm, Role::RightHand),
    (Role::LeftUpperLeg, Role::LeftLowerLeg),
    (Role::LeftLowerLeg, Role::LeftFoot),
    (Role::LeftFoot, Role::LeftToe),
    (Role::RightUpperLeg, Role::RightLowerLeg),
    (Role::RightLowerLeg, Role::RightFoot),
    (Role::RightFoot, Role::RightToe),
];

impl Roles {
    pub fn get(&self, role: Role) -> Option<usize> {
        self.0[role.index()]
    }

    pub fn set(&mut self, role: Role, joint: Option<usize>) {
        self.0[role.index()] = joint;
    }

    pub fn contains(&self, role: Role) -> bool {
        self.get(role).is_some()
    }

    /// The joint per role in [`Role::ALL`] order.
    pub fn as_array(&self) -> &[Option<usize>; NUM_ROLES] {
        &self.0
    }

    /// Roles that were found, with their joints.
    pub fn iter(&self) -> impl Iterator<Item = (Role, usize)> + '_ {
        Role::ALL.into_iter().filter_map(|r| self.get(r).map(|j| (r, j)))
    }
}

impl std::ops::Index<Role> for Roles {
    type Output = usize;
    /// # Panics
    /// If the role was not found; check with [`Roles::contains`] first.
    fn index(&self, role: Role) -> &usize {
        self.0[role.index()].as_ref().unwrap_or_else(|| panic!("no {} joint", role.name()))
    }
}

/// Why an override could not be used.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum OverrideError {
    UnknownRole(String),
    UnknownJoint { role: String, joint: String },
}

impl std::fmt::Display for OverrideError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            OverrideError::UnknownRole(r) => {
                let known: Vec<&str> = Role::ALL.iter().map(|r| r.name()).collect();
                write!(f, "unknown role '{r}' (known: {})", known.join(", "))
            }
            OverrideError::UnknownJoint { role, joint } => {
                write!(f, "'{role}' names joint '{joint}', which the skeleton does not have")
            }
        }
    }
}

/// Finds the joint of every role in a skeleton of `names` whose parents are `parents`
/// (negative for none), by name only (see [`find_roles_in`] for the geometric fallback).
///
/// # Errors
/// An override naming an unknown role or a joint the skeleton does not have.
pub fn find_roles<S: AsRef<str>>(
    names: &[S],
    parents: &[i32],
    overrides: &HashMap<String, String>,
) -> Result<Roles, OverrideError> {
    find_roles_in(names, parents, None, overrides)
}

/// Finds the joint of every role in a skeleton of `names` whose parents are `parents`
/// (negative for none).
///
/// `overrides` (role name → joint name, exact or normalized; `""` leaves the role unmapped)
/// win over everything else. Then the name conventions: the hips, unless overridden, are the
/// closest common ancestor of the two upper legs when both are found, else found by name.
///
/// With a `shape` (bone lengths and a few poses), names are only a hint: the skeleton's
/// topology and geometry find the humanoid ([`find_humanoid`]) whatever the joints are called,
/// and the name-based roles are kept only if they agree with it — legs and feet found, each
/// chain in hierarchy order, left on the geometric left. Roles the names missed are filled
/// from the geometry; when the names disagree, the geometry's roles are used.
///
/// # Errors
/// An override naming an unknown role or a joint the skeleton does not have.
pub fn find_roles_in<S: AsRef<str>>(
    names: &[S],
    parents: &[i32],
    shape: Option<&Shape>,
    overrides: &HashMap<String, String>,
) -> Result<Roles, OverrideError> {
    let normalized: Vec<String> = names.iter().map(|n| normalize_name(n.as_ref())).collect();
    let mut roles = Roles::default();
    let mut used = vec![false; names.len()];
    let mut fixed = [false; NUM_ROLES];
    for (role_name, joint) in overrides {
        let role = Role::from_name(role_name).ok_or_else(|| OverrideError::UnknownRole(role_name.clone()))?;
        fixed[role.index()] = true;
        if joint.is_empty() {
            continue;
        }
        let j = names
            .iter()
            .position(|n| n.as_ref() == joint)
            .or_else(|| {
                let k = normalize_name(joint);
                normalized.iter().position(|n| *n == k)
            })
            .ok_or_else(|| OverrideError::UnknownJoint { role: role_name.clone(), joint: joint.clone() })?;
        roles.set(role, Some(j));
        used[j] = true;
    }
    let overridden = (roles, used.clone());
    let find = |candidates: &[&str], role: Role, used: &[bool]| {
        candidates.iter().find_map(|c| {
            let c = match role.side() {
                Some((s, word)) => c.replace("{side}", word).replace("{s}", s),
                None => c.to_string(),
            };
            normalized.iter().enumerate().position(|(j, n)| !used[j] && *n == c)
        })
    };
    for role in Role::ALL {
        if fixed[role.index()] || role == Role::Hips {
            continue;
        }
        if let Some(j) = find(candidates(role), role, &used) {
            roles.set(role, Some(j));
            used[j] = true;
        }
    }
    if !fixed[Role::Hips.index()] {
        let hips = match (roles.get(Role::LeftUpperLeg), roles.get(Role::RightUpperLeg)) {
            (Some(l), Some(r)) => common_ancestor(parents, l, r),
            _ => find(candidates(Role::Hips), Role::Hips, &used),
        };
        roles.set(Role::Hips, hips);
    }
    let Some(shape) = shape else { return Ok(roles) };
    let Ok(humanoid) = find_humanoid(parents, shape) else { return Ok(roles) };
    if !names_agree(&roles, &humanoid, parents) {
        // The names are wrong or partial where it matters: start again from the overrides.
        (roles, used) = overridden;
    }
    for (role, j) in humanoid.roles.iter() {
        if !fixed[role.index()] && !roles.contains(role) && !used[j] {
            roles.set(role, Some(j));
            used[j] = true;
        }
    }
    Ok(roles)
}

/// Whether name-based roles can be trusted next to the geometry's: both legs found down to the
/// feet as chains of the hierarchy (hips above upper leg above lower leg above foot), each leg
/// on the side the geometry says, and the hips where the geometry puts them.
fn names_agree(by_name: &Roles, humanoid: &Humanoid, parents: &[i32]) -> bool {
    use Role::*;
    let chain = |roles: [Role; 4]| {
        let joints: Option<Vec<usize>> = roles.iter().map(|&r| by_name.get(r)).collect();
        joints.is_some_and(|j| j.windows(2).all(|w| is_ancestor(parents, w[0], w[1])))
    };
    let on_side =
        |upper: Role, leg: usize| by_name.get(upper).is_some_and(|j| j == leg || is_ancestor(parents, leg, j));
    chain([Hips, LeftUpperLeg, LeftLowerLeg, LeftFoot])
        && chain([Hips, RightUpperLeg, RightLowerLeg, RightFoot])
        && by_name.get(Hips) == humanoid.roles.get(Hips)
        && (!humanoid.sided || (on_side(LeftUpperLeg, humanoid.legs[0]) && on_side(RightUpperLeg, humanoid.legs[1])))
}

/// Whether `a` is a proper ancestor of `b` (any joint order; a parent cycle ends the walk).
fn is_ancestor(parents: &[i32], a: usize, b: usize) -> bool {
    let mut j = b;
    for _ in 0..parents.len() {
        match parents.get(j) {
            Some(&p) if p >= 0 => {
                j = p as usize;
                if j == a {
                    return true;
                }
            }
            _ => return false,
        }
    }
    false
}

/// What role detection may measure besides names: bone lengths and a few poses.
pub struct Shape<'a> {
    /// Each joint's rest offset from its parent (any unit; only lengths are used, so a rest pose
    /// with the legs pointing up is fine).
    pub offsets: &'a [DVec3],
    /// Each joint's end-site offset (a BVH leaf's `End Site`), if any.
    pub end_sites: &'a [Option<DVec3>],
    /// Model-space joint positions (and end-site points) in one or more poses: frames of the
    /// motion for a BVH, whose rest pose may be anything; the rest pose for an avatar. Left and
    /// right come from them. Empty: the rest pose of `offsets`.
    pub poses: &'a [ShapePose],
}

/// One pose of a [`Shape`].
#[derive(Clone, Debug, Default)]
pub struct ShapePose {
    /// Model-space position of every joint.
    pub joints: Vec<DVec3>,
    /// Model-space position of every joint's end site (`None` without one).
    pub ends: Vec<Option<DVec3>>,
}

/// A humanoid found from topology and geometry alone ([`find_humanoid`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Humanoid {
    pub roles: Roles,
    /// First joint of the left and right leg branches (the hips' children they hang from).
    pub legs: [usize; 2],
    /// First joint of the left and right arm branches (clavicles, or upper arms without).
    pub arms: [usize; 2],
    /// Whether the poses told left from right (they need toes or foot end sites); if not, the
    /// first-listed limb of each pair is taken as the left one.
    pub sided: bool,
}

/// Typical proportions of an adult, relative to thigh + shin: upper arm 0.35, forearm 0.27
/// (CMU subject 16: 0.35, 0.25; CMU Daz: 0.34, 0.29; 100STYLE: 0.37, 0.30). They tell the upper
/// arm from a long clavicle (CMU's is 0.23).
const UPPER_ARM: f64 = 0.35;
const FOREARM: f64 = 0.27;

/// Most sibling-limb pairs [`find_humanoid`] compares (the largest): a humanoid has a few dozen
/// at most (legs, arms, fingers, toes).
const MAX_LIMB_PAIRS: usize = 256;

/// Finds a humanoid in a skeleton without its names (docs/database.md, "Roles"):
/// 1. **limbs** are pairs of sibling branches of the same shape (joint tree) and length; the
///    two longest pairs where one hangs below the other's parent are the legs (the lower pair)
///    and the arms;
/// 2. the **hips** are the legs' parent; the **spine** joints run from the hips to the arms'
///    parent (spine, chest, upper chest); the **head** is at the end of the remaining branch
///    there (before a branching — eyes — or a short end joint), the neck at its start;
/// 3. along each leg's main chain the two longest consecutive bones are the thigh and shin,
///    then the foot and toe; along an arm the two bones closest to the typical upper arm and
///    forearm proportions are the arm, then the hand, the joint before them the shoulder;
/// 4. **left** is `up × forward` in the poses: up from the hips to the head, forward from the
///    feet to the toes (right-handed axes, as BVH and glTF are).
///
/// # Errors
/// The part that could not be found: the legs, the arms, a foot, a hand or the head.
pub fn find_humanoid(parents: &[i32], shape: &Shape) -> Result<Humanoid, String> {
    let n = parents.len();
    if shape.offsets.len() != n || shape.end_sites.len() != n {
        return Err(format!("{n} joints but {} offsets and {} end sites", shape.offsets.len(), shape.end_sites.len()));
    }
    let mut children = vec![Vec::new(); n];
    for (j, &p) in parents.iter().enumerate() {
        if p >= 0 && (p as usize) < n {
            children[p as usize].push(j);
        }
    }
    // Parent-first order (any input order; a cycle leaves its joints out).
    let mut order: Vec<usize> = (0..n).filter(|&j| parents[j] < 0 || parents[j] as usize >= n).collect();
    let mut k = 0;
    while k < order.len() {
        order.extend(children[order[k]].iter().copied());
        k += 1;
    }
    let bone = |j: usize| shape.offsets[j].length();
    let end = |j: usize| shape.end_sites[j].map_or(0.0, |e| e.length());
    // Reach: the longest path of bones below a joint; shape: its joint tree, as a canonical id.
    let mut reach = vec![0.0f64; n];
    let mut shape_id = vec![0usize; n];
    let mut shapes: HashMap<Vec<usize>, usize> = HashMap::new();
    for &j in order.iter().rev() {
        reach[j] = children[j].iter().map(|&c| bone(c) + reach[c]).fold(end(j), f64::max);
        let mut key: Vec<usize> = children[j].iter().map(|&c| shape_id[c]).collect();
        key.sort_unstable();
        let next = shapes.len();
        shape_id[j] = *shapes.entry(key).or_insert(next);
    }
    let limb = |c: usize| bone(c) + reach[c];
    // The main chain of a branch: follow the child with the longest reach to a leaf.
    let main_chain = |start: usize| {
        let mut chain = vec![start];
        let mut j = start;
        while let Some(&c) = children[j].iter().max_by(|&&a, &&b| limb(a).total_cmp(&limb(b))) {
            chain.push(c);
            j = c;
        }
        chain
    };
    // Bone length from each chain joint to the next (the last: its end site).
    let segments = |chain: &[usize]| -> Vec<f64> {
        (0..chain.len()).map(|i| chain.get(i + 1).map_or(end(chain[i]), |&c| bone(c))).collect()
    };
    let leg_bones = |start: usize| {
        let chain = main_chain(start);
        let s = segments(&chain);
        (0..chain.len().saturating_sub(1))
            .map(|i| (s[i] + s[i + 1], i))
            .max_by(|a, b| a.0.total_cmp(&b.0))
            .map(|(sum, i)| (sum, i, chain))
    };

    // 1. Pairs of sibling limbs of one shape and similar reach.
    let mut pairs: Vec<(usize, usize, usize)> = Vec::new(); // parent, a, b
    for p in 0..n {
        let c = &children[p];
        for (x, &a) in c.iter().enumerate() {
            for &b in &c[x + 1..] {
                let (la, lb) = (limb(a), limb(b));
                if shape_id[a] == shape_id[b] && la > 0.0 && la.min(lb) >= 0.8 * la.max(lb) {
                    pairs.push((p, a, b));
                }
            }
        }
    }
    if pairs.is_empty() {
        return Err("no pair of matching limbs (legs) found".into());
    }
    let size = |&(_, a, b): &(usize, usize, usize)| limb(a).max(limb(b));
    // Legs and arms are among the largest pairs; a hostile file with hundreds of identical
    // siblings would otherwise make the pair-of-pairs search below quadratic in ~n² pairs.
    // (A stable sort: among equal sizes the file order decides, as before.)
    if pairs.len() > MAX_LIMB_PAIRS {
        pairs.sort_by(|a, b| size(b).total_cmp(&size(a)));
        pairs.truncate(MAX_LIMB_PAIRS);
    }
    // The two longest consecutive bones below each paired limb (for limbs hanging off one joint).
    let leg_sum: HashMap<usize, Option<f64>> =
        pairs.iter().flat_map(|&(_, a, b)| [a, b]).map(|j| (j, leg_bones(j).map(|l| l.0))).collect();
    let inside = |branch: usize, j: usize| j == branch || is_ancestor(parents, branch, j);
    let mut best: Option<(f64, usize, usize)> = None;
    for (x, legs) in pairs.iter().enumerate() {
        for (y, arms) in pairs.iter().enumerate() {
            let (lp, ap) = (legs.0, arms.0);
            let below = ap == lp || is_ancestor(parents, lp, ap);
            let apart = !inside(legs.1, ap) && !inside(legs.2, ap) && !inside(arms.1, lp) && !inside(arms.2, lp);
            let comparable = size(arms) >= 0.3 * size(legs) && size(legs) >= 0.3 * size(arms);
            // Limbs hanging off one joint: the legs are the pair with the longer two bones.
            let longer = ap != lp || leg_sum[&legs.1] >= leg_sum[&arms.1];
            if x != y && below && apart && comparable && longer {
                let score = size(legs) + size(arms);
                if best.is_none_or(|b| score > b.0) {
                    best = Some((score, x, y));
                }
            }
        }
    }
    let Some((_, x, y)) = best else {
        return Err("found one pair of matching limbs but no second (legs and arms) above or beside it".into());
    };
    let (hips, leg_a, leg_b) = pairs[x];
    let (chest, arm_a, arm_b) = pairs[y];

    // 3. Leg and arm chains.
    let leg = |start: usize| -> Result<(usize, usize, usize, Option<usize>, f64), String> {
        let (sum, i, chain) = leg_bones(start).ok_or("a leg has no bones")?;
        let foot = *chain.get(i + 2).ok_or("no foot joint below a knee")?;
        Ok((chain[i], chain[i + 1], foot, chain.get(i + 3).copied(), sum))
    };
    let (la, lb) = (leg(leg_a)?, leg(leg_b)?);
    let thigh_shin = 0.5 * (la.4 + lb.4);
    let arm = |start: usize| -> Result<(Option<usize>, usize, usize, usize), String> {
        let chain = main_chain(start);
        let s = segments(&chain);
        let score = |i: usize| (s[i] / thigh_shin - UPPER_ARM).abs() + (s[i + 1] / thigh_shin - FOREARM).abs();
        let i = (0..chain.len().saturating_sub(2))
            .min_by(|&a, &b| score(a).total_cmp(&score(b)))
            .ok_or("no hand joint below an elbow")?;
        Ok((i.checked_sub(1).map(|k| chain[k]), chain[i], chain[i + 1], chain[i + 2]))
    };
    let (aa, ab) = (arm(arm_a)?, arm(arm_b)?);

    // 2. Spine and head.
    let mut spine = Vec::new();
    let mut j = chest;
    while j != hips {
        spine.push(j);
        match parents[j] {
            p if p >= 0 => j = p as usize,
            _ => break,
        }
    }
    spine.reverse();
    let neck_start = children[chest]
        .iter()
        .copied()
        .filter(|&c| c != arm_a && c != arm_b && c != leg_a && c != leg_b)
        .max_by(|&a, &b| limb(a).total_cmp(&limb(b)))
        .ok_or("no head (a branch beside the arms)")?;
    let mut neck_chain = vec![neck_start];
    let mut j = neck_start;
    while children[j].len() == 1 {
        j = children[j][0];
        neck_chain.push(j);
    }
    // A short leaf after the head is its end (`HeadTop_End`), not the head. Without end sites (a
    // glTF skin: every leaf is a bone, none says where it ends) a leaf is the skull-top marker
    // when its bone is much longer than the one before it (the skull, ~18 cm, against the
    // neck's ~10 cm); a head bone ending the chain is not.
    if neck_chain.len() >= 2 && children[j].is_empty() {
        let marker = match shape.end_sites[j] {
            Some(_) => end(j) < 0.05 * thigh_shin,
            None => bone(j) > 1.4 * bone(neck_chain[neck_chain.len() - 2]),
        };
        if marker {
            neck_chain.pop();
        }
    }
    let head = *neck_chain.last().unwrap();

    // 4. Left and right.
    let rest;
    let poses = if shape.poses.is_empty() {
        rest = [rest_pose(parents, &order, shape)];
        &rest[..]
    } else {
        shape.poses
    };
    let tip = |pose: &ShapePose, foot: usize, toe: Option<usize>| toe.map(|t| pose.joints[t]).or(pose.ends[foot]);
    let (mut legs_left, mut arms_left, mut sided) = (0.0, 0.0, false);
    for pose in poses {
        let p = &pose.joints;
        let (Some(ta), Some(tb)) = (tip(pose, la.2, la.3), tip(pose, lb.2, lb.3)) else { continue };
        let up = p[head] - p[hips];
        let forward = (ta + tb - p[la.2] - p[lb.2]) * 0.5;
        let left = up.cross(forward).normalize_or_zero();
        sided |= left != DVec3::ZERO;
        legs_left += (p[la.0] - p[lb.0]).dot(left);
        arms_left += (p[aa.1] - p[ab.1]).dot(left);
    }
    let (left_leg, right_leg) = if legs_left >= 0.0 { (la, lb) } else { (lb, la) };
    let legs = if legs_left >= 0.0 { [leg_a, leg_b] } else { [leg_b, leg_a] };
    let (left_arm, right_arm) = if arms_left >= 0.0 { (aa, ab) } else { (ab, aa) };
    let arms = if arms_left >= 0.0 { [arm_a, arm_b] } else { [arm_b, arm_a] };

    use Role::*;
    let mut roles = Roles::default();
    roles.set(Hips, Some(hips));
    for (leg, [upper, lower, foot, toe]) in [
        (left_leg, [LeftUpperLeg, LeftLowerLeg, LeftFoot, LeftToe]),
        (right_leg, [RightUpperLeg, RightLowerLeg, RightFoot, RightToe]),
    ] {
        roles.set(upper, Some(leg.0));
        roles.set(lower, Some(leg.1));
        roles.set(foot, Some(leg.2));
        roles.set(toe, leg.3);
    }
    for (arm, [shoulder, upper, lower, hand]) in [
        (left_arm, [LeftShoulder, LeftUpperArm, LeftLowerArm, LeftHand]),
        (right_arm, [RightShoulder, RightUpperArm, RightLowerArm, RightHand]),
    ] {
        roles.set(shoulder, arm.0);
        roles.set(upper, Some(arm.1));
        roles.set(lower, Some(arm.2));
        roles.set(hand, Some(arm.3));
    }
    roles.set(Spine, spine.first().copied());
    roles.set(Chest, spine.get(1).copied());
    roles.set(UpperChest, if spine.len() >= 3 { spine.last().copied() } else { None });
    roles.set(Neck, (neck_chain.len() >= 2).then_some(neck_chain[0]));
    roles.set(Head, Some(head));
    Ok(Humanoid { roles, legs, arms, sided })
}

/// The rest pose of a shape's offsets (identity rotations).
fn rest_pose(parents: &[i32], parent_first: &[usize], shape: &Shape) -> ShapePose {
    let n = parents.len();
    let mut joints = vec![DVec3::ZERO; n];
    for &j in parent_first {
        joints[j] = shape.offsets[j] + if parents[j] >= 0 { joints[parents[j] as usize] } else { DVec3::ZERO };
    }
    let ends = (0..n).map(|j| shape.end_sites[j].map(|e| joints[j] + e)).collect();
    ShapePose { joints, ends }
}

/// The opposite-side joint of every joint (itself for centre joints), for mirroring: by name
/// ([`mirror_name`]) where the other side's name exists; else, inside the limbs of a
/// `humanoid`, the joint at the same place of the opposite limb's tree.
pub fn mirror_pairs<S: AsRef<str>>(names: &[S], parents: &[i32], humanoid: Option<&Humanoid>) -> Vec<usize> {
    let mut pairs: Vec<usize> = names
        .iter()
        .enumerate()
        .map(|(j, n)| mirror_name(n.as_ref()).and_then(|m| names.iter().position(|x| x.as_ref() == m)).unwrap_or(j))
        .collect();
    let Some(h) = humanoid else { return pairs };
    let n = parents.len();
    let mut children = vec![Vec::new(); n];
    for (j, &p) in parents.iter().enumerate() {
        if p >= 0 && (p as usize) < n {
            children[p as usize].push(j);
        }
    }
    let preorder = |start: usize| {
        let (mut out, mut stack) = (Vec::new(), vec![start]);
        while let Some(j) = stack.pop() {
            out.push(j);
            stack.extend(children[j].iter().rev());
        }
        out
    };
    for [a, b] in [h.legs, h.arms] {
        let (ta, tb) = (preorder(a), preorder(b));
        if ta.len() != tb.len() {
            continue;
        }
        for (&x, &y) in ta.iter().zip(&tb) {
            if pairs[x] == x && pairs[y] == y {
                pairs[x] = y;
                pairs[y] = x;
            }
        }
    }
    pairs
}

/// The closest joint that is an ancestor of both `a` and `b` (not `a` or `b` themselves).
fn common_ancestor(parents: &[i32], a: usize, b: usize) -> Option<usize> {
    let chain = |mut j: usize| {
        let mut v = vec![j];
        while let Some(&p) = parents.get(j) {
            if p < 0 || p as usize >= j {
                break;
            }
            j = p as usize;
            v.push(j);
        }
        v
    };
    let ca = chain(a);
    chain(b).into_iter().skip(1).find(|j| ca[1..].contains(j))
}

/// The name of the opposite-side joint under the usual conventions, or `None` for a centre
/// joint. Handles `Left`/`Right` anywhere, `l`/`r` prefixes (CMU: `lfemur`, `lThigh`), and
/// `_l`/`.L`/`_L` suffixes (Unreal, Blender). Case of the changed letters is preserved.
pub fn mirror_name(name: &str) -> Option<String> {
    for (a, b) in [("Left", "Right"), ("left", "right"), ("LEFT", "RIGHT")] {
        if name.contains(a) {
            return Some(name.replacen(a, b, 1));
        }
        if name.contains(b) {
            return Some(name.replacen(b, a, 1));
        }
    }
    for (a, b) in [("_l", "_r"), ("_L", "_R"), (".l", ".r"), (".L", ".R"), ("_l_", "_r_")] {
        if let Some(stem) = name.strip_suffix(a) {
            return Some(format!("{stem}{b}"));
        }
        if let Some(stem) = name.strip_suffix(b) {
            return Some(format!("{stem}{a}"));
        }
    }
    // VRoid `J_Bip_L_UpperLeg`.
    {
        let (a, b) = ("_L_", "_R_");
        if name.contains(a) {
            return Some(name.replacen(a, b, 1));
        }
        if name.contains(b) {
            return Some(name.replacen(b, a, 1));
        }
    }
    // Prefix after an optional namespace: "l"/"r" followed by an upper-case letter (lThigh) or,
    // for all-lowercase CMU names, by a known body-part word.
    let (ns, base) = match name.rfind([':', '|']) {
        Some(i) => name.split_at(i + 1),
        None => ("", name),
    };
    let mut chars = base.chars();
    let first = chars.next()?;
    let rest = chars.as_str();
    let swap = match first {
        'l' => 'r',
        'r' => 'l',
        'L' => 'R',
        'R' => 'L',
        _ => return None,
    };
    let second = rest.chars().next()?;
    let lower_parts = [
        "hip", "femur", "tibia", "foot", "toe", "clavicle", "humerus", "radius", "wrist", "hand", "finger", "thumb",
        "thigh", "shin", "collar", "shldr", "forearm", "buttock", "index", "mid", "ring", "pinky", "eye", "ankle",
        "knee", "elbow", "arm", "leg", "upleg", "shoulder",
    ];
    let is_part = second.is_ascii_uppercase()
        || second == '_'
        || lower_parts.iter().any(|p| rest.to_ascii_lowercase().starts_with(p));
    is_part.then(|| format!("{ns}{swap}{rest}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn roles_of(names: &[&str], parents: &[i32]) -> HashMap<&'static str, String> {
        find_roles(names, parents, &HashMap::new())
            .unwrap()
            .iter()
            .map(|(r, j)| (r.name(), names[j].to_string()))
            .collect()
    }

    #[test]
    fn mirror_names_across_conventions() {
        for (a, b) in [
            ("lfemur", "rfemur"),
            ("lThigh", "rThigh"),
            ("LeftUpLeg", "RightUpLeg"),
            ("mixamorig:LeftFoot", "mixamorig:RightFoot"),
            ("thigh_l", "thigh_r"),
            ("upperarm_L", "upperarm_R"),
            ("Foot.L", "Foot.R"),
            ("leftUpperLeg", "rightUpperLeg"),
            ("J_Bip_L_UpperLeg", "J_Bip_R_UpperLeg"),
        ] {
            assert_eq!(mirror_name(a).as_deref(), Some(b));
            assert_eq!(mirror_name(b).as_deref(), Some(a));
        }
        for centre in ["root", "lowerback", "head", "hip", "Hips", "pelvis", "spine_01", "neck", "Root"] {
            assert_eq!(mirror_name(centre), None, "{centre}");
        }
    }

    #[test]
    fn role_names_round_trip_and_mirror() {
        for r in Role::ALL {
            assert_eq!(Role::from_name(r.name()), Some(r));
            assert_eq!(r.mirror().mirror(), r);
        }
        assert_eq!(Role::LeftToe.mirror(), Role::RightToe);
        assert_eq!(Role::Head.mirror(), Role::Head);
        assert_eq!(Role::LeftToe.vrm_name(), "leftToes");
    }

    /// A whole humanoid in each convention: hips, spine ×3, neck, head, arms, legs.
    #[test]
    fn finds_every_role_in_each_convention() {
        // Order of names: hips, spine, chest, upper chest, neck, head,
        // l shoulder, l upper arm, l lower arm, l hand, r shoulder, r upper arm, r lower arm, r hand,
        // l upper leg, l lower leg, l foot, l toe, r upper leg, r lower leg, r foot, r toe.
        let conventions: [(&str, [&str; 22]); 8] = [
            (
                "cmu asf",
                [
                    "root",
                    "lowerback",
                    "upperback",
                    "thorax",
                    "lowerneck",
                    "head",
                    "lclavicle",
                    "lhumerus",
                    "lradius",
                    "lwrist",
                    "rclavicle",
                    "rhumerus",
                    "rradius",
                    "rwrist",
                    "lfemur",
                    "ltibia",
                    "lfoot",
                    "ltoes",
                    "rfemur",
                    "rtibia",
                    "rfoot",
                    "rtoes",
                ],
            ),
            (
                "mixamo",
                [
                    "mixamorig:Hips",
                    "mixamorig:Spine",
                    "mixamorig:Spine1",
                    "mixamorig:Spine2",
                    "mixamorig:Neck",
                    "mixamorig:Head",
                    "mixamorig:LeftShoulder",
                    "mixamorig:LeftArm",
                    "mixamorig:LeftForeArm",
                    "mixamorig:LeftHand",
                    "mixamorig:RightShoulder",
                    "mixamorig:RightArm",
                    "mixamorig:RightForeArm",
                    "mixamorig:RightHand",
                    "mixamorig:LeftUpLeg",
                    "mixamorig:LeftLeg",
                    "mixamorig:LeftFoot",
                    "mixamorig:LeftToeBase",
                    "mixamorig:RightUpLeg",
                    "mixamorig:RightLeg",
                    "mixamorig:RightFoot",
                    "mixamorig:RightToeBase",
                ],
            ),
            (
                "unreal",
                [
                    "pelvis",
                    "spine_01",
                    "spine_02",
                    "spine_03",
                    "neck_01",
                    "head",
                    "clavicle_l",
                    "upperarm_l",
                    "lowerarm_l",
                    "hand_l",
                    "clavicle_r",
                    "upperarm_r",
                    "lowerarm_r",
                    "hand_r",
                    "thigh_l",
                    "calf_l",
                    "foot_l",
                    "ball_l",
                    "thigh_r",
                    "calf_r",
                    "foot_r",
                    "ball_r",
                ],
            ),
            (
                "xsens",
                [
                    "Pelvis",
                    "L5",
                    "T12",
                    "T8",
                    "Neck",
                    "Head",
                    "LeftShoulder",
                    "LeftUpperArm",
                    "LeftForeArm",
                    "LeftHand",
                    "RightShoulder",
                    "RightUpperArm",
                    "RightForeArm",
                    "RightHand",
                    "LeftUpperLeg",
                    "LeftLowerLeg",
                    "LeftFoot",
                    "LeftToe",
                    "RightUpperLeg",
                    "RightLowerLeg",
                    "RightFoot",
                    "RightToe",
                ],
            ),
            (
                "vrm",
                [
                    "hips",
                    "spine",
                    "chest",
                    "upperChest",
                    "neck",
                    "head",
                    "leftShoulder",
                    "leftUpperArm",
                    "leftLowerArm",
                    "leftHand",
                    "rightShoulder",
                    "rightUpperArm",
                    "rightLowerArm",
                    "rightHand",
                    "leftUpperLeg",
                    "leftLowerLeg",
                    "leftFoot",
                    "leftToes",
                    "rightUpperLeg",
                    "rightLowerLeg",
                    "rightFoot",
                    "rightToes",
                ],
            ),
            (
                "vroid",
                [
                    "J_Bip_C_Hips",
                    "J_Bip_C_Spine",
                    "J_Bip_C_Chest",
                    "J_Bip_C_UpperChest",
                    "J_Bip_C_Neck",
                    "J_Bip_C_Head",
                    "J_Bip_L_Shoulder",
                    "J_Bip_L_UpperArm",
                    "J_Bip_L_LowerArm",
                    "J_Bip_L_Hand",
                    "J_Bip_R_Shoulder",
                    "J_Bip_R_UpperArm",
                    "J_Bip_R_LowerArm",
                    "J_Bip_R_Hand",
                    "J_Bip_L_UpperLeg",
                    "J_Bip_L_LowerLeg",
                    "J_Bip_L_Foot",
                    "J_Bip_L_ToeBase",
                    "J_Bip_R_UpperLeg",
                    "J_Bip_R_LowerLeg",
                    "J_Bip_R_Foot",
                    "J_Bip_R_ToeBase",
                ],
            ),
            (
                "100style",
                [
                    "Hips",
                    "Chest",
                    "Chest2",
                    "Chest3",
                    "Neck",
                    "Head",
                    "LeftCollar",
                    "LeftShoulder",
                    "LeftElbow",
                    "LeftWrist",
                    "RightCollar",
                    "RightShoulder",
                    "RightElbow",
                    "RightWrist",
                    "LeftHip",
                    "LeftKnee",
                    "LeftAnkle",
                    "LeftToe",
                    "RightHip",
                    "RightKnee",
                    "RightAnkle",
                    "RightToe",
                ],
            ),
            (
                "cmu daz",
                [
                    "hip", "abdomen", "chest", "", "neck", "head", "lCollar", "lShldr", "lForeArm", "lHand", "rCollar",
                    "rShldr", "rForeArm", "rHand", "lThigh", "lShin", "lFoot", "lToe", "rThigh", "rShin", "rFoot",
                    "rToe",
                ],
            ),
        ];
        // hips → spine → chest → upper chest → neck → head; shoulders on the upper chest; legs on the hips.
        let parents: [i32; 22] = [-1, 0, 1, 2, 3, 4, 3, 6, 7, 8, 3, 10, 11, 12, 0, 14, 15, 16, 0, 18, 19, 20];
        for (convention, names) in conventions {
            let roles = find_roles(&names, &parents, &HashMap::new()).unwrap();
            for (k, role) in [
                Role::Hips,
                Role::Spine,
                Role::Chest,
                Role::UpperChest,
                Role::Neck,
                Role::Head,
                Role::LeftShoulder,
                Role::LeftUpperArm,
                Role::LeftLowerArm,
                Role::LeftHand,
                Role::RightShoulder,
                Role::RightUpperArm,
                Role::RightLowerArm,
                Role::RightHand,
                Role::LeftUpperLeg,
                Role::LeftLowerLeg,
                Role::LeftFoot,
                Role::LeftToe,
                Role::RightUpperLeg,
                Role::RightLowerLeg,
                Role::RightFoot,
                Role::RightToe,
            ]
            .into_iter()
            .enumerate()
            {
                if names[k].is_empty() {
                    continue;
                }
                assert_eq!(roles.get(role).map(|j| names[j]), Some(names[k]), "{convention}: {}", role.name());
            }
        }
    }

    #[test]
    fn hips_is_common_ancestor_of_the_legs() {
        // CMU ASF: legs hang off hip joints, which hang off 'root'.
        let names = ["root", "lhipjoint", "lfemur", "rhipjoint", "rfemur"];
        let parents = [-1, 0, 1, 0, 3];
        assert_eq!(roles_of(&names, &parents)["hips"], "root");
    }

    #[test]
    fn overrides_win_and_bad_ones_are_errors() {
        let names = ["pelvis", "thigh_l", "calf_l", "foot_l", "ball_l", "Head_M"];
        let parents = [-1, 0, 1, 2, 3, 0];
        let o = HashMap::from([("head".to_string(), "Head_M".to_string()), ("left_toe".to_string(), String::new())]);
        let roles = find_roles(&names, &parents, &o).unwrap();
        assert_eq!(roles.get(Role::Head), Some(5));
        assert_eq!(roles.get(Role::LeftToe), None);
        assert_eq!(roles.get(Role::LeftFoot), Some(3));
        let bad = HashMap::from([("heed".to_string(), "Head_M".to_string())]);
        assert!(find_roles(&names, &parents, &bad).unwrap_err().to_string().contains("unknown role 'heed'"));
        let missing = HashMap::from([("head".to_string(), "Kopf".to_string())]);
        assert!(find_roles(&names, &parents, &missing).unwrap_err().to_string().contains("'Kopf'"));
    }

    /// A hostile skeleton of ~1,000 identical siblings (half a million sibling pairs) is judged
    /// in bounded time, not by comparing every pair with every other.
    #[test]
    fn many_identical_siblings_are_judged_quickly() {
        let n = 1001;
        let parents: Vec<i32> = (0..n).map(|j| if j == 0 { -1 } else { 0 }).collect();
        let offsets: Vec<DVec3> =
            (0..n).map(|j| if j == 0 { DVec3::ZERO } else { DVec3::new(0.0, -0.4, 0.01 * j as f64) }).collect();
        let end_sites = vec![Some(DVec3::new(0.0, -0.4, 0.0)); n];
        let started = std::time::Instant::now();
        let found = find_humanoid(&parents, &Shape { offsets: &offsets, end_sites: &end_sites, poses: &[] });
        assert!(found.is_err(), "{found:?}");
        assert!(started.elapsed().as_secs_f64() < 1.0, "{:?}", started.elapsed());
    }
}
