//! The joint-role vocabulary for TS: the role names, and finding roles in an avatar's skeleton
//! by the same rules as the builder uses for BVH skeletons.

use crate::roles::{find_roles, Role};
use std::collections::HashMap;
use wasm_bindgen::prelude::*;

/// The roles in order as JSON: `[{"name": "hips", "vrm": "hips"}, …]`.
#[wasm_bindgen]
pub fn role_names_json() -> String {
    let list: Vec<serde_json::Value> = Role::ALL.iter().map(|r| serde_json::json!({"name": r.name(), "vrm": r.vrm_name()})).collect();
    serde_json::Value::Array(list).to_string()
}

/// The joint of each role (in role order, −1 where missing) of a skeleton given as a JSON array
/// of joint names and their parents (−1 for a root). `overrides_json`: `{"head": "Head_M"}`
/// (role → joint name; `""` unmaps), or `"{}"`. Throws on a bad override or input.
#[wasm_bindgen]
pub fn find_roles_json(names_json: &str, parents: &[i32], overrides_json: &str) -> Result<Vec<i32>, JsError> {
    let names: Vec<String> = serde_json::from_str(names_json).map_err(|e| JsError::new(&format!("joint names: {e}")))?;
    if names.len() != parents.len() {
        return Err(JsError::new(&format!("{} joint names but {} parents", names.len(), parents.len())));
    }
    let overrides: HashMap<String, String> = serde_json::from_str(overrides_json).map_err(|e| JsError::new(&format!("role overrides must be a JSON object of role → joint name: {e}")))?;
    let roles = find_roles(&names, parents, &overrides).map_err(|e| JsError::new(&format!("role overrides: {e}")))?;
    Ok(roles.as_array().iter().map(|j| j.map_or(-1, |j| j as i32)).collect())
}
