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
        LeftUpperLeg | RightUpperLeg => &["{s}femur", "{s}thigh", "{side}upperleg", "{side}upleg", "thigh{s}", "{side}thigh", "{s}upleg", "jbip{s}upperleg", "{side}hip"],
        LeftLowerLeg | RightLowerLeg => &["{s}tibia", "{s}shin", "{side}lowerleg", "{side}leg", "calf{s}", "{side}shin", "{s}leg", "jbip{s}lowerleg", "{side}knee"],
        LeftFoot | RightFoot => &["{s}foot", "{side}foot", "foot{s}", "jbip{s}foot", "{side}ankle", "{s}ankle"],
        LeftToe | RightToe => &["{s}toes", "{s}toe", "{side}toe", "{side}toebase", "{side}toes", "ball{s}", "toe{s}", "toes{s}", "{side}toe0", "jbip{s}toebase"],
        LeftShoulder | RightShoulder => &["{s}clavicle", "{s}collar", "{side}collar", "{side}clavicle", "clavicle{s}", "jbip{s}shoulder", "{side}shoulder"],
        LeftUpperArm | RightUpperArm => &["{s}humerus", "{s}shldr", "{side}upperarm", "{side}arm", "upperarm{s}", "jbip{s}upperarm", "{side}shoulder", "{s}shoulder"],
        LeftLowerArm | RightLowerArm => &["{s}radius", "{s}forearm", "{side}forearm", "{side}lowerarm", "lowerarm{s}", "jbip{s}lowerarm", "{side}elbow"],
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
            OverrideError::UnknownJoint { role, joint } => write!(f, "'{role}' names joint '{joint}', which the skeleton does not have"),
        }
    }
}

/// Finds the joint of every role in a skeleton of `names` whose parents are `parents`
/// (negative for none).
///
/// `overrides` (role name → joint name, exact or normalized; `""` leaves the role unmapped)
/// win over the name conventions. The hips, unless overridden, are the closest common ancestor
/// of the two upper legs when both are found (any convention then works), else found by name.
///
/// # Errors
/// An override naming an unknown role or a joint the skeleton does not have.
pub fn find_roles<S: AsRef<str>>(names: &[S], parents: &[i32], overrides: &HashMap<String, String>) -> Result<Roles, OverrideError> {
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
    Ok(roles)
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
    for (a, b) in [("_L_", "_R_")] {
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
        "hip", "femur", "tibia", "foot", "toe", "clavicle", "humerus", "radius", "wrist", "hand", "finger", "thumb", "thigh", "shin",
        "collar", "shldr", "forearm", "buttock", "index", "mid", "ring", "pinky", "eye", "ankle", "knee", "elbow", "arm", "leg",
        "upleg", "shoulder",
    ];
    let is_part = second.is_ascii_uppercase() || second == '_' || lower_parts.iter().any(|p| rest.to_ascii_lowercase().starts_with(p));
    is_part.then(|| format!("{ns}{swap}{rest}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn roles_of(names: &[&str], parents: &[i32]) -> HashMap<&'static str, String> {
        find_roles(names, parents, &HashMap::new()).unwrap().iter().map(|(r, j)| (r.name(), names[j].to_string())).collect()
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
            ("cmu asf", ["root", "lowerback", "upperback", "thorax", "lowerneck", "head", "lclavicle", "lhumerus", "lradius", "lwrist", "rclavicle", "rhumerus", "rradius", "rwrist", "lfemur", "ltibia", "lfoot", "ltoes", "rfemur", "rtibia", "rfoot", "rtoes"]),
            ("mixamo", ["mixamorig:Hips", "mixamorig:Spine", "mixamorig:Spine1", "mixamorig:Spine2", "mixamorig:Neck", "mixamorig:Head", "mixamorig:LeftShoulder", "mixamorig:LeftArm", "mixamorig:LeftForeArm", "mixamorig:LeftHand", "mixamorig:RightShoulder", "mixamorig:RightArm", "mixamorig:RightForeArm", "mixamorig:RightHand", "mixamorig:LeftUpLeg", "mixamorig:LeftLeg", "mixamorig:LeftFoot", "mixamorig:LeftToeBase", "mixamorig:RightUpLeg", "mixamorig:RightLeg", "mixamorig:RightFoot", "mixamorig:RightToeBase"]),
            ("unreal", ["pelvis", "spine_01", "spine_02", "spine_03", "neck_01", "head", "clavicle_l", "upperarm_l", "lowerarm_l", "hand_l", "clavicle_r", "upperarm_r", "lowerarm_r", "hand_r", "thigh_l", "calf_l", "foot_l", "ball_l", "thigh_r", "calf_r", "foot_r", "ball_r"]),
            ("xsens", ["Pelvis", "L5", "T12", "T8", "Neck", "Head", "LeftShoulder", "LeftUpperArm", "LeftForeArm", "LeftHand", "RightShoulder", "RightUpperArm", "RightForeArm", "RightHand", "LeftUpperLeg", "LeftLowerLeg", "LeftFoot", "LeftToe", "RightUpperLeg", "RightLowerLeg", "RightFoot", "RightToe"]),
            ("vrm", ["hips", "spine", "chest", "upperChest", "neck", "head", "leftShoulder", "leftUpperArm", "leftLowerArm", "leftHand", "rightShoulder", "rightUpperArm", "rightLowerArm", "rightHand", "leftUpperLeg", "leftLowerLeg", "leftFoot", "leftToes", "rightUpperLeg", "rightLowerLeg", "rightFoot", "rightToes"]),
            ("vroid", ["J_Bip_C_Hips", "J_Bip_C_Spine", "J_Bip_C_Chest", "J_Bip_C_UpperChest", "J_Bip_C_Neck", "J_Bip_C_Head", "J_Bip_L_Shoulder", "J_Bip_L_UpperArm", "J_Bip_L_LowerArm", "J_Bip_L_Hand", "J_Bip_R_Shoulder", "J_Bip_R_UpperArm", "J_Bip_R_LowerArm", "J_Bip_R_Hand", "J_Bip_L_UpperLeg", "J_Bip_L_LowerLeg", "J_Bip_L_Foot", "J_Bip_L_ToeBase", "J_Bip_R_UpperLeg", "J_Bip_R_LowerLeg", "J_Bip_R_Foot", "J_Bip_R_ToeBase"]),
            ("100style", ["Hips", "Chest", "Chest2", "Chest3", "Neck", "Head", "LeftCollar", "LeftShoulder", "LeftElbow", "LeftWrist", "RightCollar", "RightShoulder", "RightElbow", "RightWrist", "LeftHip", "LeftKnee", "LeftAnkle", "LeftToe", "RightHip", "RightKnee", "RightAnkle", "RightToe"]),
            ("cmu daz", ["hip", "abdomen", "chest", "", "neck", "head", "lCollar", "lShldr", "lForeArm", "lHand", "rCollar", "rShldr", "rForeArm", "rHand", "lThigh", "lShin", "lFoot", "lToe", "rThigh", "rShin", "rFoot", "rToe"]),
        ];
        // hips → spine → chest → upper chest → neck → head; shoulders on the upper chest; legs on the hips.
        let parents: [i32; 22] = [-1, 0, 1, 2, 3, 4, 3, 6, 7, 8, 3, 10, 11, 12, 0, 14, 15, 16, 0, 18, 19, 20];
        for (convention, names) in conventions {
            let roles = find_roles(&names, &parents, &HashMap::new()).unwrap();
            for (k, role) in [
                Role::Hips, Role::Spine, Role::Chest, Role::UpperChest, Role::Neck, Role::Head,
                Role::LeftShoulder, Role::LeftUpperArm, Role::LeftLowerArm, Role::LeftHand,
                Role::RightShoulder, Role::RightUpperArm, Role::RightLowerArm, Role::RightHand,
                Role::LeftUpperLeg, Role::LeftLowerLeg, Role::LeftFoot, Role::LeftToe,
                Role::RightUpperLeg, Role::RightLowerLeg, Role::RightFoot, Role::RightToe,
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
}
