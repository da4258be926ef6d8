//! Finding body parts by joint name across skeleton conventions (CMU ASF, CMU Daz, Xsens,
//! Mixamo, Unreal/Quaternius, VRM humanoid), and left/right pairing for mirroring.

use std::collections::HashMap;

/// Body parts the builder needs, in the order they are written to the `.mmdb` site table.
pub const ROLES: [&str; 20] = [
    "hips",
    "left_upper_leg",
    "left_lower_leg",
    "left_foot",
    "left_toe",
    "right_upper_leg",
    "right_lower_leg",
    "right_foot",
    "right_toe",
    "spine",
    "neck",
    "head",
    "left_shoulder",
    "left_upper_arm",
    "left_lower_arm",
    "left_hand",
    "right_shoulder",
    "right_upper_arm",
    "right_lower_arm",
    "right_hand",
];

/// Candidate names per limb part (normalized: lowercase, alphanumerics only, namespace
/// removed) as templates: `{s}` is the side letter (`l`/`r`), `{side}` the word
/// (`left`/`right`). Order matters: the first candidate present wins, so CMU's `lfoot`
/// (ankle) is taken before any looser match.
fn limb_candidates(part: &str) -> &'static [&'static str] {
    match part {
        //                 CMU ASF       CMU Daz      Xsens / Mixamo / VRM / Unreal
        "upper_leg" => &["{s}femur", "{s}thigh", "{side}upperleg", "{side}upleg", "thigh{s}", "{side}thigh", "{s}upleg"],
        "lower_leg" => &["{s}tibia", "{s}shin", "{side}lowerleg", "{side}leg", "calf{s}", "{side}shin", "{s}leg", "{side}knee"],
        "foot" => &["{s}foot", "{side}foot", "foot{s}", "{side}ankle", "{s}ankle"],
        "toe" => &["{s}toes", "{s}toe", "{side}toe", "{side}toebase", "{side}toes", "ball{s}", "toe{s}", "toes{s}", "{side}toe0"],
        "shoulder" => &["{s}clavicle", "{s}collar", "{side}shoulder", "clavicle{s}", "{side}clavicle"],
        "upper_arm" => &["{s}humerus", "{s}shldr", "{side}upperarm", "{side}arm", "upperarm{s}", "{s}shoulder"],
        "lower_arm" => &["{s}radius", "{s}forearm", "{side}forearm", "{side}lowerarm", "lowerarm{s}", "{side}elbow"],
        "hand" => &["{s}wrist", "{s}hand", "{side}hand", "hand{s}", "{side}wrist"],
        _ => &[],
    }
}

fn center_candidates(role: &str) -> &'static [&'static str] {
    match role {
        "spine" => &["lowerback", "abdomen", "spine", "spine01", "spine1", "l3", "chest"],
        "neck" => &["lowerneck", "neck", "neck01", "neck1", "t1"],
        "head" => &["head"],
        _ => &[],
    }
}

/// Lowercase alphanumerics of a joint name without its namespace (`mixamorig:LeftFoot` →
/// `leftfoot`, `Armature|thigh_L` → `thighl`).
pub fn normalize_name(name: &str) -> String {
    let base = name.rsplit([':', '|']).next().unwrap_or(name);
    base.chars().filter(|c| c.is_ascii_alphanumeric()).map(|c| c.to_ascii_lowercase()).collect()
}

/// The joint index playing each role. `overrides` (role → joint name) wins over conventions.
/// Roles not found are absent from the map. `hips` is the lowest common ancestor of the two
/// upper legs when not named explicitly, which works for any skeleton whose legs are found.
pub fn find_roles(names: &[String], parents: &[Option<usize>], overrides: &HashMap<String, String>) -> HashMap<&'static str, usize> {
    let normalized: Vec<String> = names.iter().map(|n| normalize_name(n)).collect();
    let find = |candidates: &[&str]| candidates.iter().find_map(|c| normalized.iter().position(|n| n == c));
    let mut roles = HashMap::new();
    for role in ROLES {
        if let Some(name) = overrides.get(role) {
            if let Some(j) = names.iter().position(|n| n == name) {
                roles.insert(role, j);
            }
            continue;
        }
        let side = if role.starts_with("left_") { Some(("l", "left")) } else if role.starts_with("right_") { Some(("r", "right")) } else { None };
        let found = if let Some((s, word)) = side {
            let part = &role[word.len() + 1..];
            let names: Vec<String> = limb_candidates(part).iter().map(|c| c.replace("{side}", word).replace("{s}", s)).collect();
            find(&names.iter().map(String::as_str).collect::<Vec<_>>())
        } else {
            find(center_candidates(role))
        };
        if let Some(j) = found {
            roles.insert(role, j);
        }
    }
    if !overrides.contains_key("hips") {
        let hips = match (roles.get("left_upper_leg"), roles.get("right_upper_leg")) {
            (Some(&l), Some(&r)) => common_ancestor(parents, l, r),
            _ => find(&["hips", "hip", "pelvis", "root"]),
        };
        if let Some(h) = hips {
            roles.insert("hips", h);
        }
    }
    roles
}

fn common_ancestor(parents: &[Option<usize>], a: usize, b: usize) -> Option<usize> {
    let chain = |mut j: usize| {
        let mut v = vec![j];
        while let Some(p) = parents[j] {
            v.push(p);
            j = p;
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

    fn roles_of(names: &[&str], parents: &[Option<usize>]) -> HashMap<&'static str, String> {
        let names: Vec<String> = names.iter().map(|s| s.to_string()).collect();
        find_roles(&names, parents, &HashMap::new()).into_iter().map(|(r, j)| (r, names[j].clone())).collect()
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
        ] {
            assert_eq!(mirror_name(a).as_deref(), Some(b));
            assert_eq!(mirror_name(b).as_deref(), Some(a));
        }
        for centre in ["root", "lowerback", "head", "hip", "Hips", "pelvis", "spine_01", "neck", "Root"] {
            assert_eq!(mirror_name(centre), None, "{centre}");
        }
    }

    #[test]
    fn finds_roles_in_each_convention() {
        // Minimal chains: hips → thigh → shin → foot → toe for each side.
        let conventions: [[&str; 9]; 5] = [
            ["root", "lfemur", "ltibia", "lfoot", "ltoes", "rfemur", "rtibia", "rfoot", "rtoes"],
            ["hip", "lThigh", "lShin", "lFoot", "lToe", "rThigh", "rShin", "rFoot", "rToe"],
            ["mixamorig:Hips", "mixamorig:LeftUpLeg", "mixamorig:LeftLeg", "mixamorig:LeftFoot", "mixamorig:LeftToeBase", "mixamorig:RightUpLeg", "mixamorig:RightLeg", "mixamorig:RightFoot", "mixamorig:RightToeBase"],
            ["pelvis", "thigh_l", "calf_l", "foot_l", "ball_l", "thigh_r", "calf_r", "foot_r", "ball_r"],
            ["Pelvis", "LeftUpperLeg", "LeftLowerLeg", "LeftFoot", "LeftToe", "RightUpperLeg", "RightLowerLeg", "RightFoot", "RightToe"],
        ];
        let parents = [None, Some(0), Some(1), Some(2), Some(3), Some(0), Some(5), Some(6), Some(7)];
        for names in conventions {
            let roles = roles_of(&names, &parents);
            assert_eq!(roles["hips"], names[0]);
            assert_eq!(roles["left_upper_leg"], names[1]);
            assert_eq!(roles["left_foot"], names[3]);
            assert_eq!(roles["left_toe"], names[4]);
            assert_eq!(roles["right_lower_leg"], names[6]);
            assert_eq!(roles["right_toe"], names[8]);
        }
    }

    #[test]
    fn hips_is_common_ancestor_of_the_legs() {
        // CMU ASF: legs hang off hip joints, which hang off 'root'.
        let names = ["root", "lhipjoint", "lfemur", "rhipjoint", "rfemur"];
        let parents = [None, Some(0), Some(1), Some(0), Some(3)];
        assert_eq!(roles_of(&names, &parents)["hips"], "root");
    }
}
