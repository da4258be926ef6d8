//! The joint-role vocabulary for TS: the role names, and finding roles in an avatar's skeleton
//! by the same rules as the builder uses for BVH skeletons.

use crate::roles::{find_roles, find_roles_in, Role, Shape, ShapePose};
use glam::DVec3;
use std::collections::HashMap;
use wasm_bindgen::prelude::*;

/// The roles in order as JSON: `[{"name": "hips", "vrm": "hips"}, …]`.
#[wasm_bindgen]
pub fn role_names_json() -> String {
    let list: Vec<serde_json::Value> =
        Role::ALL.iter().map(|r| serde_json::json!({"name": r.name(), "vrm": r.vrm_name()})).collect();
    serde_json::Value::Array(list).to_string()
}

/// The joint of each role (in role order, −1 where missing) of a skeleton given as a JSON array
/// of joint names and their parents (−1 for a root). `overrides_json`: `{"head": "Head_M"}`
/// (role → joint name; `""` unmaps), or `"{}"`. Throws on a bad override or input.
#[wasm_bindgen]
pub fn find_roles_json(names_json: &str, parents: &[i32], overrides_json: &str) -> Result<Vec<i32>, JsError> {
    let names: Vec<String> =
        serde_json::from_str(names_json).map_err(|e| JsError::new(&format!("joint names: {e}")))?;
    if names.len() != parents.len() {
        return Err(JsError::new(&format!("{} joint names but {} parents", names.len(), parents.len())));
    }
    let overrides: HashMap<String, String> = serde_json::from_str(overrides_json)
        .map_err(|e| JsError::new(&format!("role overrides must be a JSON object of role → joint name: {e}")))?;
    let roles = find_roles(&names, parents, &overrides).map_err(|e| JsError::new(&format!("role overrides: {e}")))?;
    Ok(roles.as_array().iter().map(|j| j.map_or(-1, |j| j as i32)).collect())
}

/// As [`find_roles_json`], with the skeleton's rest pose: `rest_positions` are the joints'
/// model-space positions (x, y, z per joint, any unit, any facing), so that topology and
/// geometry find the roles when the names match no convention (`roles::find_humanoid`: limbs as
/// pairs of matching branches, thigh and shin as the two longest leg bones, left from the pose).
#[wasm_bindgen]
pub fn find_roles_rest_json(
    names_json: &str,
    parents: &[i32],
    rest_positions: &[f32],
    overrides_json: &str,
) -> Result<Vec<i32>, JsError> {
    let names: Vec<String> =
        serde_json::from_str(names_json).map_err(|e| JsError::new(&format!("joint names: {e}")))?;
    let n = names.len();
    if parents.len() != n || rest_positions.len() != 3 * n {
        return Err(JsError::new(&format!(
            "{n} joint names but {} parents and {} rest coordinates",
            parents.len(),
            rest_positions.len()
        )));
    }
    let overrides: HashMap<String, String> = serde_json::from_str(overrides_json)
        .map_err(|e| JsError::new(&format!("role overrides must be a JSON object of role → joint name: {e}")))?;
    let joints: Vec<DVec3> =
        rest_positions.chunks_exact(3).map(|p| DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64)).collect();
    let offsets: Vec<DVec3> = (0..n)
        .map(|j| match parents[j] {
            p if p >= 0 && (p as usize) < n => joints[j] - joints[p as usize],
            _ => joints[j],
        })
        .collect();
    let end_sites = vec![None; n];
    let poses = [ShapePose { joints, ends: vec![None; n] }];
    let shape = Shape { offsets: &offsets, end_sites: &end_sites, poses: &poses };
    let roles = find_roles_in(&names, parents, Some(&shape), &overrides)
        .map_err(|e| JsError::new(&format!("role overrides: {e}")))?;
    Ok(roles.as_array().iter().map(|j| j.map_or(-1, |j| j as i32)).collect())
}
