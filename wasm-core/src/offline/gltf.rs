//! glTF 2.0 animation import: the animation clips of a `.glb`/`.gltf` file and VRM Animation
//! (`.vrma`, a GLB with the `VRMC_vrm_animation` extension) become takes the database builder
//! reads like BVH files ([`Bvh`]), so everything after parsing — roles, units and up axis
//! measured on the motion, resampling, retargeting another skeleton — is the same as for BVH.
//!
//! Per animation: the skeleton is the subtree of the lowest common ancestor of the animated
//! nodes, the skin joints and the VRM humanoid bones (the nodes above it are baked into its root
//! motion); every channel (LINEAR, STEP, CUBICSPLINE) is sampled at the clip's key rate (its
//! keys' spacing when uniform, else 60 fps). Rotations are re-expressed so that the rest pose of
//! the file has identity rotations — the BVH convention the builder expects — leaving every
//! joint's world motion unchanged: `q'ⱼ = Wₚ·qⱼ·Wⱼ⁻¹`, offsets `Wₚ·(Sₚ·tⱼ)`, with `W` the rest
//! world rotations and `S` the accumulated uniform scale. A VRM humanoid map (VRMA, VRM 1.0,
//! VRM 0.x) names the roles ([`Bvh::role_hints`]); without one the importer's rules (names,
//! topology) find them.
//!
//! Untrusted input: every index, offset, count and value is checked; errors name the file and
//! what is wrong ([`Error::Gltf`]); allocation is bounded by the input size and
//! [`crate::limits`].

use crate::bvh::{Bvh, BvhJoint, Channel};
use crate::error::{Error, Result};
use crate::limits::{quote, MAX_ABS_BVH_VALUE, MAX_FRAMES, MAX_JOINTS, MAX_NAME_BYTES};
use crate::roles::Role;
use glam::{DMat4, DQuat, DVec3, EulerRot};
use serde_json::Value;
use std::borrow::Cow;

/// One animation clip of a glTF file as a take.
pub struct GltfTake {
    /// The animation's name (`animation3` when it has none).
    pub clip: String,
    pub bvh: Bvh,
}

/// The rate clips are sampled at when their keys are not evenly spaced (frames per second).
pub const DEFAULT_SAMPLE_FPS: f64 = 60.0;
/// The highest key rate kept as it is; denser keys are sampled at this rate.
pub const MAX_SAMPLE_FPS: f64 = 240.0;
/// Samples (frames × channels) a file may expand to, at least; more for larger files.
const MIN_VALUE_BUDGET: usize = 1 << 23;

const GLB_MAGIC: &[u8; 4] = b"glTF";
const CHUNK_JSON: u32 = 0x4E4F_534A;
const CHUNK_BIN: u32 = 0x004E_4942;

/// Whether `bytes` look like glTF (a GLB header or JSON text) rather than BVH.
pub fn looks_like_gltf(bytes: &[u8]) -> bool {
    let text = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    bytes.starts_with(GLB_MAGIC) || text.iter().find(|b| !b.is_ascii_whitespace()) == Some(&b'{')
}

/// Parses a `.glb`, `.gltf` (buffers embedded as `data:` URIs) or `.vrma` file into one take
/// per animation. `file` names the input in messages.
///
/// # Errors
/// [`Error::Gltf`] naming the file and what is wrong: not glTF 2.0, a truncated or corrupt
/// container, an index or accessor out of range, an external buffer, a sparse accessor,
/// non-increasing key times, a non-finite value, a scale that is not uniform or is animated, no
/// animation, or a skeleton larger than [`MAX_JOINTS`].
pub fn parse(file: &str, bytes: &[u8]) -> Result<Vec<GltfTake>> {
    let err = |m: String| Error::gltf(file, m);
    let (json, bin) = container(bytes).map_err(err)?;
    let doc = Document::new(&json, bin, bytes.len()).map_err(err)?;
    let animations = doc.array("animations");
    if animations.is_empty() {
        return Err(err(format!("no animations: the file has {} nodes and {} meshes but nothing moves (drop it as an avatar, or export the clips with it)", doc.nodes.len(), doc.array("meshes").len())));
    }
    let mut names: Vec<String> = Vec::new();
    let mut takes = Vec::with_capacity(animations.len());
    for (i, animation) in animations.iter().enumerate() {
        let mut clip = animation
            .get("name")
            .and_then(Value::as_str)
            .filter(|n| !n.is_empty())
            .map_or_else(|| format!("animation{i}"), |n| truncate(n, 64));
        if names.contains(&clip) {
            clip = format!("{clip}.{i}");
        }
        names.push(clip.clone());
        let bvh = doc.take(animation).map_err(|m| err(format!("animation {} ({i}): {m}", quote(&clip))))?;
        takes.push(GltfTake { clip, bvh });
    }
    Ok(takes)
}

/// The JSON and the GLB binary chunk (none for `.gltf` text).
fn container(bytes: &[u8]) -> std::result::Result<(Value, Option<&[u8]>), String> {
    if bytes.starts_with(GLB_MAGIC) {
        let word =
            |at: usize| -> Option<u32> { bytes.get(at..at + 4).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]])) };
        let (Some(version), Some(length)) = (word(4), word(8)) else {
            return Err(format!("truncated GLB header: {} bytes, a header has 12", bytes.len()));
        };
        if version != 2 {
            return Err(format!("GLB version {version}: only glTF 2.0 is read"));
        }
        if length as usize > bytes.len() {
            return Err(format!("truncated GLB: its header says {length} bytes, the file has {}", bytes.len()));
        }
        let end = length as usize;
        let (mut at, mut json, mut bin) = (12usize, None, None);
        while at < end {
            let (Some(len), Some(kind)) = (word(at), word(at + 4)) else {
                return Err(format!("truncated GLB: a chunk header at byte {at} runs past the end"));
            };
            let start = at + 8;
            let stop = start.checked_add(len as usize).filter(|&s| s <= end).ok_or_else(|| {
                format!(
                    "truncated GLB: the chunk at byte {at} says {len} bytes, {} are left",
                    end.saturating_sub(start)
                )
            })?;
            match kind {
                CHUNK_JSON if json.is_none() => json = Some(&bytes[start..stop]),
                CHUNK_BIN if bin.is_none() && json.is_some() => bin = Some(&bytes[start..stop]),
                _ => {}
            }
            if json.is_none() {
                return Err("the first GLB chunk is not JSON".into());
            }
            at = stop + (4 - stop % 4) % 4;
        }
        let json = json.ok_or("the GLB has no chunks")?;
        let value = serde_json::from_slice(json).map_err(|e| format!("the GLB's JSON: {e}"))?;
        return Ok((value, bin));
    }
    if looks_like_gltf(bytes) {
        let text = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
        let value = serde_json::from_slice(text).map_err(|e| format!("glTF JSON: {e}"))?;
        return Ok((value, None));
    }
    if bytes.windows(9).take(64).any(|w| w.eq_ignore_ascii_case(b"HIERARCHY")) {
        return Err("this is BVH text, not glTF (name it .bvh)".into());
    }
    Err("not a glTF file: a .glb/.vrma starts with 'glTF', a .gltf is JSON".into())
}

/// A node's rest transform and its place in the hierarchy.
struct Node {
    name: String,
    parent: Option<usize>,
    children: Vec<usize>,
    translation: DVec3,
    rotation: DQuat,
    /// Per axis; the skeleton's nodes must be uniform.
    scale: DVec3,
    /// Carries a mesh or camera (a leaf like that is no joint).
    attachment: bool,
}

struct Document<'a> {
    json: &'a Value,
    bin: Option<&'a [u8]>,
    nodes: Vec<Node>,
    /// Role → node, from a VRM humanoid map.
    humanoid: Vec<(Role, usize)>,
    /// Skin joints of every skin.
    skin_joints: Vec<usize>,
    /// Samples allowed in all (grows with the input).
    budget: usize,
}

type R<T> = std::result::Result<T, String>;

fn index(v: &Value, what: &str, len: usize) -> R<usize> {
    let i = v.as_u64().ok_or_else(|| format!("{what} is not an index"))?;
    if i as usize >= len || i > u32::MAX as u64 {
        return Err(format!("{what} is {i}, but there are {len}"));
    }
    Ok(i as usize)
}

fn vector<const N: usize>(v: Option<&Value>, default: [f64; N], what: &str) -> R<[f64; N]> {
    let Some(v) = v else { return Ok(default) };
    let a = v.as_array().filter(|a| a.len() == N).ok_or_else(|| format!("{what} is not {N} numbers"))?;
    let mut out = [0.0; N];
    for (o, x) in out.iter_mut().zip(a) {
        *o = x
            .as_f64()
            .filter(|x| x.is_finite() && x.abs() <= MAX_ABS_BVH_VALUE)
            .ok_or_else(|| format!("{what} has a value that is not a finite number"))?;
    }
    Ok(out)
}

fn truncate(name: &str, max: usize) -> String {
    let mut end = name.len().min(max);
    while !name.is_char_boundary(end) {
        end -= 1;
    }
    name[..end].to_string()
}

impl<'a> Document<'a> {
    fn new(json: &'a Value, bin: Option<&'a [u8]>, input_bytes: usize) -> R<Document<'a>> {
        if !json.is_object() {
            return Err("the glTF JSON is not an object".into());
        }
        let version = json.pointer("/asset/version").and_then(Value::as_str).unwrap_or("");
        if !version.starts_with("2.") {
            return Err(format!(
                "asset.version {}: only glTF 2.0 is read",
                quote(if version.is_empty() { "(missing)" } else { version })
            ));
        }
        let mut doc = Document {
            json,
            bin,
            nodes: Vec::new(),
            humanoid: Vec::new(),
            skin_joints: Vec::new(),
            budget: MIN_VALUE_BUDGET.max(2 * input_bytes),
        };
        doc.read_nodes()?;
        doc.read_humanoid()?;
        for (s, skin) in doc.array("skins").iter().enumerate() {
            for j in skin.get("joints").and_then(Value::as_array).map_or(&[][..], Vec::as_slice) {
                doc.skin_joints.push(index(j, &format!("skin {s}: a joint"), doc.nodes.len())?);
            }
        }
        Ok(doc)
    }

    fn array(&self, key: &str) -> &'a [Value] {
        self.json.get(key).and_then(Value::as_array).map_or(&[], Vec::as_slice)
    }

    fn read_nodes(&mut self) -> R<()> {
        let raw = self.array("nodes");
        let mut used: Vec<String> = Vec::with_capacity(raw.len());
        for (i, n) in raw.iter().enumerate() {
            let what = |f: &str| format!("node {i} {f}");
            let mut name = n
                .get("name")
                .and_then(Value::as_str)
                .filter(|s| !s.trim().is_empty())
                .map_or_else(|| format!("node{i}"), |s| truncate(s.trim(), MAX_NAME_BYTES - 8));
            if used.contains(&name) {
                name = format!("{name}.{i}");
            }
            used.push(name.clone());
            let (translation, rotation, scale) = if let Some(m) = n.get("matrix") {
                let m: [f64; 16] = vector(Some(m), [0.0; 16], &what("matrix"))?;
                let (s, r, t) = DMat4::from_cols_array(&m).to_scale_rotation_translation();
                if !(s.is_finite() && r.is_finite()) || s.min_element() <= 0.0 {
                    return Err(format!(
                        "node {} has a matrix that is not a rotation, translation and positive scale",
                        quote(&name)
                    ));
                }
                (t, r.normalize(), s)
            } else {
                let t = vector(n.get("translation"), [0.0; 3], &what("translation"))?;
                let r = vector(n.get("rotation"), [0.0, 0.0, 0.0, 1.0], &what("rotation"))?;
                let s = vector(n.get("scale"), [1.0; 3], &what("scale"))?;
                let q = DQuat::from_array(r);
                if q.length() < 1e-6 {
                    return Err(format!("node {} has a zero rotation quaternion", quote(&name)));
                }
                (DVec3::from(t), q.normalize(), DVec3::from(s))
            };
            let mut children = Vec::new();
            for c in n.get("children").and_then(Value::as_array).map_or(&[][..], Vec::as_slice) {
                children.push(index(c, &what("children: a child"), raw.len())?);
            }
            let attachment = n.get("mesh").is_some() || n.get("camera").is_some();
            self.nodes.push(Node { name, parent: None, children, translation, rotation, scale, attachment });
        }
        for p in 0..self.nodes.len() {
            for c in self.nodes[p].children.clone() {
                if let Some(other) = self.nodes[c].parent {
                    return Err(format!(
                        "node {} is a child of both {} and {}",
                        quote(&self.nodes[c].name),
                        quote(&self.nodes[other].name),
                        quote(&self.nodes[p].name)
                    ));
                }
                self.nodes[c].parent = Some(p);
            }
        }
        // No node may be its own ancestor (a cycle would never end).
        for start in 0..self.nodes.len() {
            let (mut n, mut steps) = (start, 0);
            while let Some(p) = self.nodes[n].parent {
                n = p;
                steps += 1;
                if steps > self.nodes.len() {
                    return Err(format!(
                        "node {} is its own ancestor (the hierarchy has a cycle)",
                        quote(&self.nodes[start].name)
                    ));
                }
            }
        }
        Ok(())
    }

    /// The VRM humanoid map: VRM Animation, VRM 1.0 or VRM 0.x.
    fn read_humanoid(&mut self) -> R<()> {
        let ext = self.json.get("extensions");
        let n = self.nodes.len();
        let mut map: Vec<(String, Value)> = Vec::new();
        let (source, bones) = if let Some(b) = ext.and_then(|e| e.pointer("/VRMC_vrm_animation/humanoid/humanBones")) {
            ("VRMC_vrm_animation", b)
        } else if let Some(b) = ext.and_then(|e| e.pointer("/VRMC_vrm/humanoid/humanBones")) {
            ("VRMC_vrm", b)
        } else if let Some(b) = ext.and_then(|e| e.pointer("/VRM/humanoid/humanBones")) {
            ("VRM", b)
        } else {
            return Ok(());
        };
        match bones {
            Value::Object(o) => {
                map.extend(o.iter().map(|(k, v)| (k.clone(), v.get("node").cloned().unwrap_or(Value::Null))))
            }
            Value::Array(a) => map.extend(a.iter().filter_map(|b| {
                Some((b.get("bone")?.as_str()?.to_string(), b.get("node").cloned().unwrap_or(Value::Null)))
            })),
            _ => return Err(format!("{source} humanoid: humanBones is neither an object nor a list")),
        }
        for (bone, node) in map {
            if let Some(role) = Role::ALL.into_iter().find(|r| r.vrm_name() == bone) {
                let node = index(&node, &format!("{source} humanoid: {} → node", quote(&bone)), n)?;
                self.humanoid.push((role, node));
            }
        }
        Ok(())
    }

    fn buffer(&self, i: usize) -> R<Cow<'a, [u8]>> {
        let buffers = self.array("buffers");
        let b = buffers.get(i).ok_or_else(|| format!("buffer {i} does not exist (there are {})", buffers.len()))?;
        let declared =
            b.get("byteLength").and_then(Value::as_u64).ok_or_else(|| format!("buffer {i} has no byteLength"))?
                as usize;
        let bytes: Cow<'a, [u8]> = match b.get("uri").and_then(Value::as_str) {
            None => match (i, self.bin) {
                (0, Some(bin)) => Cow::Borrowed(bin),
                _ => return Err(format!("buffer {i} has no uri and the file has no GLB binary chunk for it")),
            },
            Some(uri) if uri.starts_with("data:") => {
                let data = uri
                    .split_once(";base64,")
                    .map(|(_, d)| d)
                    .ok_or_else(|| format!("buffer {i}: a data: URI that is not base64"))?;
                Cow::Owned(base64(data).ok_or_else(|| format!("buffer {i}: its data: URI is not valid base64"))?)
            }
            Some(uri) => {
                return Err(format!(
                    "buffer {i} is the external file {}: embed it (a .glb, or a data: URI in the .gltf)",
                    quote(uri)
                ))
            }
        };
        if bytes.len() < declared {
            return Err(format!("buffer {i} says {declared} bytes but holds {}", bytes.len()));
        }
        Ok(bytes)
    }

    /// An accessor's elements as f64 (normalized integers scaled), `components` per element.
    fn accessor(&self, i: usize, components: &[usize], what: &str) -> R<(Vec<f64>, usize)> {
        let accessors = self.array("accessors");
        let a = accessors
            .get(i)
            .ok_or_else(|| format!("{what}: accessor {i} does not exist (there are {})", accessors.len()))?;
        let at = |m: String| format!("{what} (accessor {i}): {m}");
        if a.get("sparse").is_some() {
            return Err(at("sparse accessors are not read; export without sparse storage".into()));
        }
        let count = a.get("count").and_then(Value::as_u64).ok_or_else(|| at("no count".into()))? as usize;
        let n = match a.get("type").and_then(Value::as_str) {
            Some("SCALAR") => 1,
            Some("VEC2") => 2,
            Some("VEC3") => 3,
            Some("VEC4") => 4,
            Some("MAT4") => 16,
            t => return Err(at(format!("type {} is not one used by animations", quote(t.unwrap_or("(missing)"))))),
        };
        if !components.contains(&n) {
            return Err(at(format!("has {n} components per element, expected {components:?}")));
        }
        let ctype = a.get("componentType").and_then(Value::as_u64).unwrap_or(0);
        let normalized = a.get("normalized").and_then(Value::as_bool).unwrap_or(false);
        let size = match ctype {
            5120 | 5121 => 1,
            5122 | 5123 => 2,
            5125 | 5126 => 4,
            c => return Err(at(format!("componentType {c} is not a glTF component type"))),
        };
        let element = n * size;
        let Some(view) = a.get("bufferView") else {
            // No buffer view: all zeros (glTF 2.0 §3.6.2.3), bounded by the same budget.
            if count.saturating_mul(n) > self.budget {
                return Err(at(format!("{count} elements without data exceed what the file can hold")));
            }
            return Ok((vec![0.0; count * n], n));
        };
        let views = self.array("bufferViews");
        let v = index(view, &at("bufferView".into()), views.len()).map(|k| &views[k])?;
        let buffer = self.buffer(index(
            v.get("buffer").unwrap_or(&Value::Null),
            &at("its buffer view's buffer".into()),
            self.array("buffers").len(),
        )?)?;
        let view_offset = v.get("byteOffset").and_then(Value::as_u64).unwrap_or(0) as usize;
        let view_length =
            v.get("byteLength").and_then(Value::as_u64).ok_or_else(|| at("its buffer view has no byteLength".into()))?
                as usize;
        let view_bytes =
            view_offset.checked_add(view_length).and_then(|end| buffer.get(view_offset..end)).ok_or_else(|| {
                at(format!(
                    "its buffer view (bytes {view_offset}..+{view_length}) runs past its buffer ({} bytes)",
                    buffer.len()
                ))
            })?;
        let stride = v.get("byteStride").and_then(Value::as_u64).map_or(element, |s| s as usize);
        if stride < element {
            return Err(at(format!("byteStride {stride} is less than an element ({element} bytes)")));
        }
        let offset = a.get("byteOffset").and_then(Value::as_u64).unwrap_or(0) as usize;
        let needed = if count == 0 {
            0
        } else {
            (count - 1).checked_mul(stride).and_then(|x| x.checked_add(offset + element)).unwrap_or(usize::MAX)
        };
        if needed > view_bytes.len() {
            return Err(at(format!("{count} elements need {needed} bytes, its buffer view has {}", view_bytes.len())));
        }
        let mut out = Vec::with_capacity(count * n);
        for e in 0..count {
            let base = offset + e * stride;
            for c in 0..n {
                let b = &view_bytes[base + c * size..base + (c + 1) * size];
                let x = match ctype {
                    5126 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
                    5125 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
                    5120 => (b[0] as i8) as f64,
                    5121 => b[0] as f64,
                    5122 => i16::from_le_bytes([b[0], b[1]]) as f64,
                    _ => u16::from_le_bytes([b[0], b[1]]) as f64,
                };
                let x = if normalized {
                    match ctype {
                        5120 => (x / 127.0).max(-1.0),
                        5121 => x / 255.0,
                        5122 => (x / 32767.0).max(-1.0),
                        5123 => x / 65535.0,
                        _ => x,
                    }
                } else {
                    x
                };
                if !x.is_finite() || x.abs() > MAX_ABS_BVH_VALUE {
                    return Err(at(format!(
                        "element {e} has a value that is not a finite number below {MAX_ABS_BVH_VALUE:e}"
                    )));
                }
                out.push(x);
            }
        }
        Ok((out, n))
    }

    /// The lowest common ancestor of `nodes`, within the tree holding most of them.
    fn common_ancestor(&self, nodes: &[usize]) -> usize {
        let top = |mut n: usize| {
            while let Some(p) = self.nodes[n].parent {
                n = p;
            }
            n
        };
        let mut tops: Vec<(usize, usize)> = Vec::new();
        for &n in nodes {
            let t = top(n);
            match tops.iter_mut().find(|(k, _)| *k == t) {
                Some(e) => e.1 += 1,
                None => tops.push((t, 1)),
            }
        }
        let tree = tops.iter().max_by_key(|(_, c)| *c).map_or(0, |t| t.0);
        let chain = |mut n: usize| {
            let mut c = vec![n];
            while let Some(p) = self.nodes[n].parent {
                n = p;
                c.push(p);
            }
            c.reverse();
            c
        };
        let mut common: Option<Vec<usize>> = None;
        for &n in nodes.iter().filter(|&&n| top(n) == tree) {
            let c = chain(n);
            common = Some(match common {
                None => c,
                Some(prev) => prev.iter().zip(&c).take_while(|(a, b)| a == b).map(|(a, _)| *a).collect(),
            });
        }
        common.and_then(|c| c.last().copied()).unwrap_or(tree)
    }

    /// One animation as a take.
    fn take(&self, animation: &Value) -> R<Bvh> {
        let channels = animation.get("channels").and_then(Value::as_array).map_or(&[][..], Vec::as_slice);
        let samplers = animation.get("samplers").and_then(Value::as_array).map_or(&[][..], Vec::as_slice);
        // Sampled channels: (node, path, sampler).
        let mut tracks: Vec<Track> = Vec::new();
        for (c, ch) in channels.iter().enumerate() {
            let what = format!("channel {c}");
            let Some(target) = ch.get("target") else { return Err(format!("{what} has no target")) };
            let path = target.get("path").and_then(Value::as_str).unwrap_or("");
            let path = match path {
                "translation" => Path::Translation,
                "rotation" => Path::Rotation,
                "scale" => Path::Scale,
                "weights" => continue, // morph targets: not motion
                p => return Err(format!("{what} animates {}, not a node's translation, rotation or scale", quote(p))),
            };
            let Some(node) = target.get("node") else { continue }; // an extension's target (KHR_animation_pointer)
            let node = index(node, &format!("{what}'s target node"), self.nodes.len())?;
            if tracks.iter().any(|t| t.node == node && t.path == path) {
                continue; // the first channel of a node and path wins
            }
            let s = index(ch.get("sampler").unwrap_or(&Value::Null), &format!("{what}'s sampler"), samplers.len())?;
            tracks.push(self.track(
                &samplers[s],
                node,
                path,
                &format!("{what} (node {}, {})", quote(&self.nodes[node].name), path.name()),
            )?);
        }
        if tracks.is_empty() {
            return Err("no channel moves a node".into());
        }

        // The skeleton: the lowest common ancestor of what moves and what is a bone.
        let mut members: Vec<usize> = tracks.iter().map(|t| t.node).collect();
        members.extend(self.humanoid.iter().map(|&(_, n)| n));
        members.extend(&self.skin_joints);
        let root = match self.humanoid.iter().find(|(r, _)| *r == Role::Hips) {
            // A humanoid's hips carry it: nodes above (a VRMA's "root") are baked into its motion,
            // nodes elsewhere (look-at targets) are not the body.
            Some(&(_, hips)) => hips,
            None => self.common_ancestor(&members),
        };
        let mut joints = vec![root];
        let mut k = 0;
        while k < joints.len() {
            for &c in &self.nodes[joints[k]].children {
                let n = &self.nodes[c];
                let leaf_attachment = n.attachment && n.children.is_empty() && !members.contains(&c);
                if !leaf_attachment {
                    joints.push(c);
                }
            }
            if joints.len() > MAX_JOINTS {
                return Err(format!(
                    "the skeleton under {} has more than {MAX_JOINTS} nodes",
                    quote(&self.nodes[root].name)
                ));
            }
            k += 1;
        }
        let mut chain = Vec::new();
        let mut n = root;
        while let Some(p) = self.nodes[n].parent {
            chain.push(p);
            n = p;
        }
        chain.reverse();
        for &n in chain.iter().chain(&joints) {
            let s = self.nodes[n].scale;
            if (s - DVec3::splat(s.x)).abs().max_element() > 1e-4 * s.x.abs() || s.x <= 0.0 {
                return Err(format!(
                    "node {} has the scale [{}, {}, {}]: a skeleton takes only a positive uniform scale",
                    quote(&self.nodes[n].name),
                    s.x,
                    s.y,
                    s.z
                ));
            }
        }
        for t in
            tracks.iter().filter(|t| t.path == Path::Scale && (chain.contains(&t.node) || joints.contains(&t.node)))
        {
            let rest = self.nodes[t.node].scale.x;
            if t.values.iter().any(|&v| (v - rest).abs() > 1e-3 * rest) {
                return Err(format!(
                    "node {} has its scale animated: only rotation and translation are taken",
                    quote(&self.nodes[t.node].name)
                ));
            }
        }

        // The rate and the frames.
        let start = tracks.iter().map(|t| t.times[0]).fold(f64::INFINITY, f64::min);
        let end = tracks.iter().map(|t| *t.times.last().unwrap()).fold(f64::NEG_INFINITY, f64::max);
        let duration = end - start;
        if duration <= 0.0 {
            return Err("every channel has a single key time: one pose, no motion to build from".into());
        }
        let fps = key_rate(&tracks);
        let frames = (duration * fps + 1e-6).floor() as usize + 1;
        let translated: Vec<bool> = joints
            .iter()
            .enumerate()
            .map(|(k, &j)| {
                k == 0
                    || tracks
                        .iter()
                        .any(|t| t.node == j && t.path == Path::Translation && t.moves(self.nodes[j].translation))
            })
            .collect();
        let num_channels: usize = translated.iter().map(|&t| if t { 6 } else { 3 }).sum();
        if frames > MAX_FRAMES || frames.saturating_mul(num_channels) > self.budget {
            return Err(format!("{duration:.1} s at {fps:.0} fps is {frames} frames of {num_channels} values: more than the file can hold"));
        }

        // Rest: world rotations W and accumulated scales S (the chain's rest included).
        let position = |j: usize| joints.iter().position(|&x| x == j);
        let mut chain_rest = Xform::IDENTITY;
        for &c in &chain {
            chain_rest = chain_rest.then(&self.nodes[c].rest());
        }
        let mut world_rotation = vec![DQuat::IDENTITY; joints.len()];
        let mut world_scale = vec![1.0; joints.len()];
        let mut parent_of = vec![None; joints.len()];
        for (k, &j) in joints.iter().enumerate() {
            let node = &self.nodes[j];
            let (pr, ps) = if k == 0 {
                (chain_rest.rotation, chain_rest.scale)
            } else {
                let p = position(node.parent.unwrap()).unwrap();
                parent_of[k] = Some(p);
                (world_rotation[p], world_scale[p])
            };
            world_rotation[k] = (pr * node.rotation).normalize();
            world_scale[k] = ps * node.scale.x;
        }

        // Sample every frame: local transforms, the chain, then the BVH channels.
        let mut values = Vec::with_capacity(frames * num_channels);
        let mut local_t = vec![DVec3::ZERO; self.nodes.len()];
        let mut local_r = vec![DQuat::IDENTITY; self.nodes.len()];
        let relevant: Vec<usize> = chain.iter().chain(&joints).copied().collect();
        let mut root_offset = DVec3::ZERO;
        for f in 0..frames {
            let time = start + f as f64 / fps;
            for &n in &relevant {
                local_t[n] = self.nodes[n].translation;
                local_r[n] = self.nodes[n].rotation;
            }
            for t in &tracks {
                match t.path {
                    Path::Translation => local_t[t.node] = t.vec3(time),
                    Path::Rotation => local_r[t.node] = t.quat(time),
                    Path::Scale => {}
                }
            }
            let mut chain_now = Xform::IDENTITY;
            for &c in &chain {
                chain_now = chain_now.then(&Xform {
                    translation: local_t[c],
                    rotation: local_r[c],
                    scale: self.nodes[c].scale.x,
                });
            }
            for (k, &j) in joints.iter().enumerate() {
                let (rotation, translation) = match parent_of[k] {
                    None => {
                        let world = chain_now.then(&Xform {
                            translation: local_t[j],
                            rotation: local_r[j],
                            scale: self.nodes[j].scale.x,
                        });
                        if f == 0 {
                            root_offset = chain_rest.then(&self.nodes[j].rest()).translation;
                        }
                        (world.rotation * world_rotation[k].inverse(), world.translation)
                    }
                    Some(p) => (
                        world_rotation[p] * local_r[j] * world_rotation[k].inverse(),
                        world_rotation[p] * (world_scale[p] * local_t[j]),
                    ),
                };
                if translated[k] {
                    values.extend([translation.x, translation.y, translation.z]);
                }
                let (z, y, x) = rotation.normalize().to_euler(EulerRot::ZYX);
                values.extend([z.to_degrees(), y.to_degrees(), x.to_degrees()]);
            }
        }
        if let Some(bad) = values.iter().position(|v| !v.is_finite() || v.abs() > MAX_ABS_BVH_VALUE) {
            return Err(format!(
                "frame {} has a value that is not a finite number below {MAX_ABS_BVH_VALUE:e}",
                bad / num_channels
            ));
        }

        let mut bvh_joints = Vec::with_capacity(joints.len());
        let mut first_channel = 0;
        for (k, &j) in joints.iter().enumerate() {
            let node = &self.nodes[j];
            let offset = match parent_of[k] {
                None => root_offset,
                Some(p) => world_rotation[p] * (world_scale[p] * node.translation),
            };
            let mut channels = Vec::with_capacity(6);
            if translated[k] {
                channels.extend([Channel::PosX, Channel::PosY, Channel::PosZ]);
            }
            channels.extend([Channel::RotZ, Channel::RotY, Channel::RotX]);
            bvh_joints.push(BvhJoint {
                name: node.name.clone(),
                parent: parent_of[k],
                offset,
                first_channel,
                channels,
                end_site: None,
            });
            first_channel += if translated[k] { 6 } else { 3 };
        }
        let role_hints = self
            .humanoid
            .iter()
            .filter(|(_, n)| joints.contains(n))
            .map(|&(r, n)| (r.name().to_string(), self.nodes[n].name.clone()))
            .collect();
        Ok(Bvh { joints: bvh_joints, num_channels, num_frames: frames, frame_time: 1.0 / fps, values, role_hints })
    }

    fn track(&self, sampler: &Value, node: usize, path: Path, what: &str) -> R<Track> {
        let interpolation = match sampler.get("interpolation").and_then(Value::as_str).unwrap_or("LINEAR") {
            "LINEAR" => Interpolation::Linear,
            "STEP" => Interpolation::Step,
            "CUBICSPLINE" => Interpolation::Cubic,
            i => return Err(format!("{what}: interpolation {} is not LINEAR, STEP or CUBICSPLINE", quote(i))),
        };
        let (times, _) = self.accessor(
            index(
                sampler.get("input").unwrap_or(&Value::Null),
                &format!("{what}: the sampler's input"),
                self.array("accessors").len(),
            )?,
            &[1],
            &format!("{what}: key times"),
        )?;
        let width = if path == Path::Rotation { 4 } else { 3 };
        let (values, _) = self.accessor(
            index(
                sampler.get("output").unwrap_or(&Value::Null),
                &format!("{what}: the sampler's output"),
                self.array("accessors").len(),
            )?,
            &[width],
            &format!("{what}: values"),
        )?;
        if times.is_empty() {
            return Err(format!("{what}: no keys"));
        }
        if let Some(k) = times.windows(2).position(|w| w[1] < w[0]) {
            return Err(format!(
                "{what}: key times go back at key {} ({} s after {} s)",
                k + 1,
                times[k + 1],
                times[k]
            ));
        }
        let per_key = if interpolation == Interpolation::Cubic { 3 * width } else { width };
        if values.len() != times.len() * per_key {
            return Err(format!(
                "{what}: {} keys but {} values (expected {})",
                times.len(),
                values.len() / width,
                times.len() * per_key / width
            ));
        }
        if times[0] < -1e6 || *times.last().unwrap() > 1e6 {
            return Err(format!("{what}: key times beyond ±10⁶ s"));
        }
        if path == Path::Rotation {
            for k in 0..values.len() / 4 {
                let q = &values[4 * k..4 * k + 4];
                if (interpolation != Interpolation::Cubic || k % 3 == 1)
                    && (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt() < 1e-6
                {
                    return Err(format!(
                        "{what}: key {} is a zero quaternion",
                        if interpolation == Interpolation::Cubic { k / 3 } else { k }
                    ));
                }
            }
        }
        Ok(Track { node, path, interpolation, times, values })
    }
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Path {
    Translation,
    Rotation,
    Scale,
}

impl Path {
    fn name(self) -> &'static str {
        match self {
            Path::Translation => "translation",
            Path::Rotation => "rotation",
            Path::Scale => "scale",
        }
    }
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Interpolation {
    Linear,
    Step,
    Cubic,
}

struct Track {
    node: usize,
    path: Path,
    interpolation: Interpolation,
    times: Vec<f64>,
    /// Per key: the value, or for CUBICSPLINE the in-tangent, value and out-tangent.
    values: Vec<f64>,
}

impl Track {
    fn width(&self) -> usize {
        if self.path == Path::Rotation {
            4
        } else {
            3
        }
    }

    /// Key `k`'s value (`part` 0 in-tangent, 1 value, 2 out-tangent for CUBICSPLINE).
    fn key(&self, k: usize, part: usize) -> &[f64] {
        let w = self.width();
        let at = if self.interpolation == Interpolation::Cubic { (3 * k + part) * w } else { k * w };
        &self.values[at..at + w]
    }

    /// Samples at `time`: (w components, held before the first and after the last key).
    fn sample(&self, time: f64, out: &mut [f64; 4]) -> bool {
        let w = self.width();
        let n = self.times.len();
        let after = self.times.partition_point(|&t| t <= time);
        if after == 0
            || after == n
            || self.interpolation == Interpolation::Step
            || self.times[after] <= self.times[after - 1]
        {
            let k = if after == 0 { 0 } else { after - 1 };
            out[..w].copy_from_slice(self.key(k, 1));
            return false;
        }
        let (k0, k1) = (after - 1, after);
        let dt = self.times[k1] - self.times[k0];
        let s = (time - self.times[k0]) / dt;
        match self.interpolation {
            Interpolation::Cubic => {
                let (p0, m0, p1, m1) = (self.key(k0, 1), self.key(k0, 2), self.key(k1, 1), self.key(k1, 0));
                let (s2, s3) = (s * s, s * s * s);
                for c in 0..w {
                    out[c] = (2.0 * s3 - 3.0 * s2 + 1.0) * p0[c]
                        + (s3 - 2.0 * s2 + s) * dt * m0[c]
                        + (-2.0 * s3 + 3.0 * s2) * p1[c]
                        + (s3 - s2) * dt * m1[c];
                }
                false
            }
            _ => {
                let (a, b) = (self.key(k0, 1), self.key(k1, 1));
                for c in 0..w {
                    out[c] = a[c] + (b[c] - a[c]) * s;
                }
                // Rotations slerp (LINEAR): the caller redoes them from the two keys.
                self.path == Path::Rotation
            }
        }
    }

    fn vec3(&self, time: f64) -> DVec3 {
        let mut v = [0.0; 4];
        self.sample(time, &mut v);
        DVec3::new(v[0], v[1], v[2])
    }

    fn quat(&self, time: f64) -> DQuat {
        let mut v = [0.0; 4];
        if self.sample(time, &mut v) {
            let after = self.times.partition_point(|&t| t <= time);
            let (k0, k1) = (after - 1, after);
            let s = (time - self.times[k0]) / (self.times[k1] - self.times[k0]);
            let (a, b) = (self.key(k0, 1), self.key(k1, 1));
            return DQuat::from_xyzw(a[0], a[1], a[2], a[3])
                .normalize()
                .slerp(DQuat::from_xyzw(b[0], b[1], b[2], b[3]).normalize(), s);
        }
        DQuat::from_xyzw(v[0], v[1], v[2], v[3]).normalize()
    }

    /// Whether a translation track leaves `rest` anywhere.
    fn moves(&self, rest: DVec3) -> bool {
        let scale = rest.length().max(1e-3);
        (0..self.times.len()).any(|k| {
            let v = self.key(k, 1);
            (DVec3::new(v[0], v[1], v[2]) - rest).length() > 1e-6 * scale
        })
    }
}

/// A uniform-scale transform: rotation, translation, scale.
#[derive(Clone, Copy)]
struct Xform {
    translation: DVec3,
    rotation: DQuat,
    scale: f64,
}

impl Xform {
    const IDENTITY: Xform = Xform { translation: DVec3::ZERO, rotation: DQuat::IDENTITY, scale: 1.0 };

    /// `self` applied after `child` (the child's world transform under `self`).
    fn then(&self, child: &Xform) -> Xform {
        Xform {
            translation: self.translation + self.rotation * (self.scale * child.translation),
            rotation: (self.rotation * child.rotation).normalize(),
            scale: self.scale * child.scale,
        }
    }
}

impl Node {
    fn rest(&self) -> Xform {
        Xform { translation: self.translation, rotation: self.rotation, scale: self.scale.x }
    }
}

/// The clip's key rate: the spacing of its keys when every track's is the same and even, else
/// [`DEFAULT_SAMPLE_FPS`]; never above [`MAX_SAMPLE_FPS`].
fn key_rate(tracks: &[Track]) -> f64 {
    let mut step: Option<f64> = None;
    for t in tracks.iter().filter(|t| t.times.len() > 2) {
        let d = (t.times[t.times.len() - 1] - t.times[0]) / (t.times.len() - 1) as f64;
        let even = t.times.windows(2).all(|w| ((w[1] - w[0]) - d).abs() <= 1e-3 * d + 1e-6);
        match step {
            _ if !even || d <= 0.0 => return DEFAULT_SAMPLE_FPS,
            Some(s) if (s - d).abs() > 1e-3 * s => return DEFAULT_SAMPLE_FPS,
            _ => step = Some(d),
        }
    }
    match step {
        Some(d) => (1.0 / d).clamp(1.0, MAX_SAMPLE_FPS),
        None => DEFAULT_SAMPLE_FPS,
    }
}

/// Standard base64 (RFC 4648, padding optional, whitespace ignored); `None` on anything else.
fn base64(text: &str) -> Option<Vec<u8>> {
    let mut out = Vec::with_capacity(text.len() / 4 * 3);
    let (mut acc, mut bits) = (0u32, 0u32);
    for c in text.bytes() {
        let v = match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' | b'-' => 62,
            b'/' | b'_' => 63,
            b'=' => break,
            c if c.is_ascii_whitespace() => continue,
            _ => return None,
        };
        acc = (acc << 6) | v as u32;
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
            acc &= (1 << bits) - 1;
        }
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn euler_channels_recompose_the_quaternion() {
        // The BVH side composes [Zrotation Yrotation Xrotation] as Rz·Ry·Rx.
        let q = DQuat::from_euler(EulerRot::YXZ, 0.7, -1.2, 2.5);
        let (z, y, x) = q.to_euler(EulerRot::ZYX);
        let back = DQuat::from_rotation_z(z) * DQuat::from_rotation_y(y) * DQuat::from_rotation_x(x);
        assert!(back.dot(q).abs() > 1.0 - 1e-12, "{back:?} vs {q:?}");
    }

    #[test]
    fn base64_decodes() {
        assert_eq!(base64("aGVsbG8=").unwrap(), b"hello");
        assert_eq!(base64("aGVsbG8").unwrap(), b"hello");
        assert!(base64("a*b").is_none());
    }

    #[test]
    fn not_gltf_is_named() {
        let e = parse("x.glb", b"HIERARCHY\nROOT Hips").err().unwrap().to_string();
        assert!(e.starts_with("x.glb: ") && e.contains("BVH"), "{e}");
        let e = parse("x.glb", b"glTF\x01\0\0\0\x0c\0\0\0").err().unwrap().to_string();
        assert!(e.contains("GLB version 1"), "{e}");
    }
}
