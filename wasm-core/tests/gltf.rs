//! glTF animation import (`mmcore::gltf`): a GLB written here from the synthetic humanoid BVH
//! reads back as the same motion joint by joint (world positions, whatever the bones' own axes),
//! builds a database, and damaged copies — truncated at every length, mutated at random — are
//! errors naming the file, never a panic, a hang or an allocation beyond the bound.

use crate::hostile;

use glam::{DQuat, DVec3};
use hostile::{alloc, humanoid_bvh, mutate, Rng};
use mmcore::config::BuildConfig;
use mmcore::kinematics::local_to_model;
use mmcore::{build, gltf, Bvh, Source};
use serde_json::json;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::time::{Duration, Instant};

/// A fixed rotation per bone: the GLB's bone axes differ from the BVH's by it.
fn axes(j: usize) -> DQuat {
    DQuat::from_euler(
        glam::EulerRot::XYZ,
        0.3 * (j % 5) as f64 - 0.6,
        0.7 * (j % 3) as f64 - 0.7,
        0.45 * (j % 4) as f64 - 0.6,
    )
}

/// The BVH as a GLB: one node per joint (rest rotation `axes(j)`, the motion re-expressed so the
/// world motion is the BVH's), every joint's rotation and the root's translation animated.
fn glb_from(bvh: &Bvh) -> Vec<u8> {
    let n = bvh.joints.len();
    let parent_axes = |j: usize| bvh.joints[j].parent.map_or(DQuat::IDENTITY, axes);
    let mut bin: Vec<u8> = Vec::new();
    let mut views = Vec::new();
    let mut accessors = Vec::new();
    let mut push = |values: &[f32], kind: &str, count: usize| {
        let offset = bin.len();
        for v in values {
            bin.extend_from_slice(&v.to_le_bytes());
        }
        views.push(json!({"buffer": 0, "byteOffset": offset, "byteLength": values.len() * 4}));
        accessors.push(json!({"bufferView": views.len() - 1, "componentType": 5126, "count": count, "type": kind}));
        accessors.len() - 1
    };
    let times: Vec<f32> = (0..bvh.num_frames).map(|f| (f as f64 * bvh.frame_time) as f32).collect();
    let input = push(&times, "SCALAR", bvh.num_frames);
    let (mut samplers, mut channels) = (Vec::new(), Vec::new());
    for j in 0..n {
        let (mut t, mut q) = (Vec::new(), Vec::new());
        for f in 0..bvh.num_frames {
            let (lt, lr) = bvh.local_transform(f, j);
            let p = parent_axes(j).inverse();
            t.extend((p * lt).to_array().map(|x| x as f32));
            q.extend((p * lr * axes(j)).normalize().to_array().map(|x| x as f32));
        }
        let out = push(&q, "VEC4", bvh.num_frames);
        samplers.push(json!({"input": input, "output": out}));
        channels.push(json!({"sampler": samplers.len() - 1, "target": {"node": j, "path": "rotation"}}));
        if j == 0 {
            let out = push(&t, "VEC3", bvh.num_frames);
            samplers.push(json!({"input": input, "output": out, "interpolation": "LINEAR"}));
            channels.push(json!({"sampler": samplers.len() - 1, "target": {"node": j, "path": "translation"}}));
        }
    }
    let nodes: Vec<_> = (0..n)
        .map(|j| {
            let children: Vec<usize> = (0..n).filter(|&c| bvh.joints[c].parent == Some(j)).collect();
            let p = parent_axes(j).inverse();
            let mut node = json!({"name": bvh.joints[j].name, "translation": (p * bvh.joints[j].offset).to_array(), "rotation": (p * axes(j)).normalize().to_array()});
            if !children.is_empty() {
                node["children"] = json!(children);
            }
            node
        })
        .collect();
    let doc = json!({
        "asset": {"version": "2.0"},
        "scene": 0, "scenes": [{"nodes": [0]}],
        "nodes": nodes,
        "buffers": [{"byteLength": bin.len()}],
        "bufferViews": views, "accessors": accessors,
        "animations": [{"name": "walk", "samplers": samplers, "channels": channels}],
    });
    let mut text = serde_json::to_vec(&doc).unwrap();
    while !text.len().is_multiple_of(4) {
        text.push(b' ');
    }
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let total = 12 + 8 + text.len() + 8 + bin.len();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(text.len() as u32).to_le_bytes());
    out.extend_from_slice(&0x4E4F_534Au32.to_le_bytes());
    out.extend_from_slice(&text);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(&0x004E_4942u32.to_le_bytes());
    out.extend_from_slice(&bin);
    out
}

/// World positions of every joint of `bvh` at `frame`, by joint name.
fn world(bvh: &Bvh, frame: usize) -> Vec<(String, DVec3)> {
    let n = bvh.joints.len();
    let parents: Vec<i32> = bvh.joints.iter().map(|j| j.parent.map_or(-1, |p| p as i32)).collect();
    let (mut lp, mut lr) = (vec![DVec3::ZERO; n], vec![DQuat::IDENTITY; n]);
    for j in 0..n {
        (lp[j], lr[j]) = bvh.local_transform(frame, j);
    }
    let (mut wp, mut wr) = (vec![DVec3::ZERO; n], vec![DQuat::IDENTITY; n]);
    local_to_model(&parents, 0..n, None, &lp, &lr, &mut wp, &mut wr);
    bvh.joints.iter().map(|j| j.name.clone()).zip(wp).collect()
}

#[test]
fn a_glb_reads_back_as_the_bvh_motion_and_builds() {
    let bvh = Bvh::parse("humanoid.bvh", humanoid_bvh(120).as_bytes()).unwrap();
    let glb = glb_from(&bvh);
    let takes = gltf::parse("humanoid.glb", &glb).unwrap();
    assert_eq!(takes.len(), 1);
    assert_eq!(takes[0].clip, "walk");
    let back = &takes[0].bvh;
    assert_eq!(back.num_frames, bvh.num_frames);
    assert!((back.frame_time - bvh.frame_time).abs() < 1e-6, "{} vs {}", back.frame_time, bvh.frame_time);
    assert!(back.role_hints.is_empty());
    let mut worst = 0.0f64;
    for f in (0..bvh.num_frames).step_by(7) {
        let a = world(&bvh, f);
        let b = world(back, f);
        for (name, p) in &a {
            let q = b.iter().find(|(n, _)| n == name).unwrap_or_else(|| panic!("{name} missing")).1;
            worst = worst.max((*p - q).length());
        }
    }
    // f32 storage in the GLB: micrometres.
    assert!(worst < 1e-4, "largest joint gap {worst} m");
    // The rest pose is the file's (identity rotations: the BVH convention).
    let rest_gap = bvh
        .joints
        .iter()
        .map(|j| (j.offset - back.joints.iter().find(|k| k.name == j.name).unwrap().offset).length())
        .fold(0.0, f64::max);
    assert!(rest_gap < 1e-5, "{rest_gap}");
    let out = build(&BuildConfig::default(), &[Source { name: "humanoid.glb".into(), bvh: back.clone() }]).unwrap();
    assert!(out.database.num_frames > 100);
}

#[test]
fn a_vrm_humanoid_map_names_the_roles() {
    let bvh = Bvh::parse("humanoid.bvh", humanoid_bvh(60).as_bytes()).unwrap();
    let glb = glb_from(&bvh);
    // Rename every node and add the map: the hips and the left foot.
    let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    let mut doc: serde_json::Value = serde_json::from_slice(&glb[20..20 + json_len]).unwrap();
    let names: Vec<String> =
        doc["nodes"].as_array().unwrap().iter().map(|n| n["name"].as_str().unwrap().to_string()).collect();
    for (i, node) in doc["nodes"].as_array_mut().unwrap().iter_mut().enumerate() {
        node["name"] = json!(format!("Bone{i}"));
    }
    let foot = names.iter().position(|n| n == "lfoot").unwrap();
    doc["extensions"] = json!({"VRMC_vrm_animation": {"specVersion": "1.0", "humanoid": {"humanBones": {"hips": {"node": 0}, "leftFoot": {"node": foot}, "jaw": {"node": 1}}}}});
    let mut text = serde_json::to_vec(&doc).unwrap();
    while !text.len().is_multiple_of(4) {
        text.push(b' ');
    }
    let mut out = glb[..12].to_vec();
    out.extend_from_slice(&(text.len() as u32).to_le_bytes());
    out.extend_from_slice(&glb[16..20]);
    out.extend_from_slice(&text);
    out.extend_from_slice(&glb[20 + json_len..]);
    let total = out.len() as u32;
    out[8..12].copy_from_slice(&total.to_le_bytes());
    let takes = gltf::parse("renamed.vrma", &out).unwrap();
    let hints = &takes[0].bvh.role_hints;
    assert!(hints.contains(&("hips".to_string(), "Bone0".to_string())), "{hints:?}");
    assert!(hints.contains(&("left_foot".to_string(), format!("Bone{foot}"))), "{hints:?}");
    assert_eq!(hints.len(), 2, "bones outside the vocabulary (jaw) are not roles: {hints:?}");
}

#[test]
fn damaged_glbs_are_errors_naming_the_file_never_panics() {
    let bvh = Bvh::parse("humanoid.bvh", humanoid_bvh(40).as_bytes()).unwrap();
    let glb = glb_from(&bvh);
    let mut cases: Vec<Vec<u8>> = (0..glb.len()).step_by(53).map(|n| glb[..n].to_vec()).collect();
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    cases.extend((0..400).map(|_| mutate(&glb, &mut rng)));
    let (mut ok, mut errors) = (0, 0);
    for bytes in &cases {
        let started = Instant::now();
        let (result, peak) = alloc::measure(|| catch_unwind(AssertUnwindSafe(|| gltf::parse("case.glb", bytes))));
        let result = result.unwrap_or_else(|_| panic!("panicked on a {}-byte case", bytes.len()));
        assert!(started.elapsed() < Duration::from_secs(5), "took {:?}", started.elapsed());
        let bound = 64 * bytes.len() + (64 << 20);
        assert!(peak <= bound, "peak heap {peak} B beyond {bound} B");
        match result {
            Ok(takes) => {
                ok += 1;
                for t in takes {
                    assert_eq!(t.bvh.values.len(), t.bvh.num_frames * t.bvh.num_channels);
                    assert!(t.bvh.values.iter().all(|v| v.is_finite()));
                }
            }
            Err(e) => {
                errors += 1;
                let m = e.to_string();
                assert!(m.starts_with("case.glb: ") && m.len() < 500, "{m}");
            }
        }
    }
    assert!(errors > cases.len() / 2, "{errors} errors of {}", cases.len());
    assert!(ok > 0);
}

#[test]
fn a_key_far_in_the_future_is_refused_before_allocating() {
    let doc = json!({
        "asset": {"version": "2.0"},
        "nodes": [{"name": "a"}],
        "buffers": [{"byteLength": 32, "uri": "data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAC6W0k="}],
        "bufferViews": [{"buffer": 0, "byteOffset": 24, "byteLength": 8}, {"buffer": 0, "byteLength": 24}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 2, "type": "SCALAR"},
            {"bufferView": 1, "componentType": 5126, "count": 2, "type": "VEC3"}
        ],
        "animations": [{"samplers": [{"input": 0, "output": 1}], "channels": [{"sampler": 0, "target": {"node": 0, "path": "translation"}}]}]
    });
    // Keys at 0 and 900 000 s: 54 million frames at 60 fps.
    let (result, peak) = alloc::measure(|| gltf::parse("far.gltf", &serde_json::to_vec(&doc).unwrap()));
    let e = result.err().unwrap().to_string();
    assert!(e.starts_with("far.gltf: animation animation0 (0): ") && e.contains("more than the file can hold"), "{e}");
    assert!(peak < 1 << 20, "{peak} B");
}
