//! `RawBuilder`: builds a database in the page from BVH files and glTF/GLB/VRMA animations
//! (drag and drop, the API), and `bvh_info`.

use super::{js_error, Kind, LiveToken};
use crate::builder::{self, Source};
use crate::config::BuildConfig;
use crate::{format, Bvh};
use wasm_bindgen::prelude::*;

/// Add files, then `build()`.
#[wasm_bindgen]
pub struct RawBuilder {
    config: BuildConfig,
    sources: Vec<Source>,
    warnings: Vec<String>,
    footprint: Option<crate::limits::BuildFootprint>,
    _live: LiveToken,
}

#[wasm_bindgen]
impl RawBuilder {
    /// `config_json` uses the `mmdb build --config` schema; `"{}"` means the defaults.
    #[wasm_bindgen(constructor)]
    pub fn new(config_json: &str) -> Result<RawBuilder, JsError> {
        let config = BuildConfig::from_json(config_json).map_err(js_error)?;
        Ok(RawBuilder {
            config,
            sources: Vec::new(),
            warnings: Vec::new(),
            footprint: None,
            _live: LiveToken::new(Kind::Builder),
        })
    }

    /// Parses a BVH file now, so a bad file is reported (file:line) when it is added.
    pub fn add_bvh(&mut self, name: &str, bytes: &[u8]) -> Result<(), JsError> {
        let bvh = Bvh::parse(name, bytes).map_err(js_error)?;
        self.sources.push(Source { name: name.to_string(), bvh });
        Ok(())
    }

    /// Parses a glTF/GLB/VRMA file now (each animation a take, `name#clip` when there are
    /// several) and returns the names of the takes added, as a JSON array.
    pub fn add_gltf(&mut self, name: &str, bytes: &[u8]) -> Result<String, JsError> {
        let takes = crate::gltf::parse(name, bytes).map_err(js_error)?;
        let single = takes.len() == 1;
        let mut names = Vec::with_capacity(takes.len());
        for t in takes {
            let source = if single { name.to_string() } else { format!("{name}#{}", t.clip) };
            names.push(source.clone());
            self.sources.push(Source { name: source, bvh: t.bvh });
        }
        Ok(serde_json::to_string(&names).unwrap_or_default())
    }

    /// The `.mmdb` bytes of a database built from the added files.
    pub fn build(&mut self) -> Result<Vec<u8>, JsError> {
        let out = builder::build(&self.config, &self.sources).map_err(js_error)?;
        self.warnings = out.warnings;
        self.footprint = Some(out.footprint);
        Ok(format::to_bytes(&out.database))
    }

    /// What the last successful build was estimated to need before it started, as JSON:
    /// `{"bytes": …, "frames": …, "limit": …}` (`limits::BuildFootprint`), or `null`.
    pub fn footprint_json(&self) -> String {
        self.footprint.map_or("null".into(), |f| {
            serde_json::json!({"bytes": f.bytes(), "frames": f.frames, "limit": crate::limits::MAX_BUILD_BYTES})
                .to_string()
        })
    }

    /// Warnings of the last build, as a JSON array of strings.
    pub fn warnings_json(&self) -> String {
        serde_json::to_string(&self.warnings).unwrap_or_default()
    }
}

/// Parses BVH bytes and returns a JSON summary (joints, frames, fps); throws on bad input.
#[wasm_bindgen]
pub fn bvh_info(name: &str, bytes: &[u8]) -> Result<String, JsError> {
    let bvh = Bvh::parse(name, bytes).map_err(js_error)?;
    Ok(serde_json::json!({
        "num_joints": bvh.joints.len(),
        "num_frames": bvh.num_frames,
        "fps": bvh.fps(),
        "joints": bvh.joints.iter().map(|j| j.name.as_str()).collect::<Vec<_>>(),
    })
    .to_string())
}
