//! Human- and machine-readable summaries of a database (`mmdb inspect`, `mmdb dump`, and the
//! same JSON from WASM so pages and tests see exactly what the CLI reports).

use crate::database::Database;
use serde_json::{json, Value};

/// What a page needs to know of a database to run it, as JSON — the joints, sites, features,
/// clips and tags, and the toe height in contact (`toe_floor`: computed once at load, an FK pass
/// over a quarter of the frames) — without a scan of its arrays: the web `Database` reads this
/// at every load, before the first frame.
pub fn header(db: &Database, toe_floor: Option<f32>) -> Value {
    json!({
        "format_version": crate::format::VERSION,
        "num_frames": db.num_frames,
        "fps": db.fps,
        "duration_s": db.duration(),
        "num_joints": db.num_joints(),
        "num_features": db.num_features(),
        "joints": db.skeleton.names.iter().zip(&db.skeleton.parents).map(|(n, p)| json!({"name": n, "parent": p})).collect::<Vec<_>>(),
        "sites": db.skeleton.sites.iter().map(|s| json!({"name": s.name, "joint": s.joint, "offset": s.offset.to_array()})).collect::<Vec<_>>(),
        "features": db.groups.iter().map(|g| json!({
            "name": g.name, "kind": g.kind, "trajectory": g.is_trajectory, "axes": g.axes,
            "joint": db.skeleton.names[g.joint], "offsets": g.offsets, "weight": g.weight,
            "dims": [g.first_dim, g.first_dim + g.num_dims],
            "mean": &db.feature_mean[g.first_dim..g.first_dim + g.num_dims],
            "scale": db.feature_scale[g.first_dim],
        })).collect::<Vec<_>>(),
        "clips": db.clips.iter().map(|c| json!({
            "name": c.name, "source": c.source, "start": c.start, "end": c.end, "mirrored": c.mirrored,
            "source_fps": c.source_fps, "source_start": c.source_start, "scale": c.scale, "root_scale": c.root_scale,
        })).collect::<Vec<_>>(),
        "tags": db.tags.iter().map(|t| json!({
            "name": t.name, "ranges": t.ranges, "frames": t.ranges.iter().map(|(s, e)| e - s).sum::<u32>(),
        })).collect::<Vec<_>>(),
        "toe_height_in_contact": toe_floor,
    })
}

/// [`header`] and what scanning the arrays adds — valid frames, each feature dimension's range,
/// the share of frames each foot is in contact — as JSON (`mmdb inspect --json`). `size_bytes`
/// is the file size when known.
pub fn summary(db: &Database, size_bytes: Option<usize>) -> Value {
    let d = db.num_features();
    let mut lo = vec![f32::INFINITY; d];
    let mut hi = vec![f32::NEG_INFINITY; d];
    for row in db.features.chunks_exact(d) {
        for i in 0..d {
            lo[i] = lo[i].min(row[i]);
            hi[i] = hi[i].max(row[i]);
        }
    }
    let share = |side: usize| {
        db.contacts.iter().skip(side).step_by(2).filter(|&&c| c != 0).count() as f64 / db.num_frames.max(1) as f64
    };
    let mut v = header(db, db.toe_height_in_contact());
    let m = v.as_object_mut().expect("an object");
    m.insert("num_valid_frames".into(), json!(db.valid.iter().filter(|&&v| v != 0).count()));
    m.insert("size_bytes".into(), json!(size_bytes));
    m.insert("feature_range".into(), json!(lo.iter().zip(&hi).map(|(l, h)| [l, h]).collect::<Vec<_>>()));
    m.insert("contact_share".into(), json!([share(0), share(1)]));
    v
}

/// Every array of the database as JSON (for cross-language tests). f32 values print as the
/// shortest decimal that reads back to the same f32.
pub fn dump(db: &Database) -> Value {
    let flat3 = |v: &[glam::Vec3]| v.iter().flat_map(|x| x.to_array()).collect::<Vec<f32>>();
    let summary = summary(db, None);
    // The velocities a frame plays with (derived, not stored), every frame's at once.
    let (velocities, angular) =
        crate::database::pose_velocities(db.num_joints(), db.fps, &db.clips, &db.local_positions, &db.local_rotations);
    json!({
        "num_frames": db.num_frames,
        "num_joints": db.num_joints(),
        "fps": db.fps,
        "num_features": db.num_features(),
        "joint_names": db.skeleton.names,
        "parents": db.skeleton.parents,
        "offsets": flat3(&db.skeleton.offsets),
        "local_positions": flat3(&db.local_positions),
        "local_rotations": db.local_rotations.iter().flat_map(|q| q.to_array()).collect::<Vec<f32>>(),
        "local_velocities": flat3(&velocities),
        "local_angular_velocities": flat3(&angular),
        "contacts": db.contacts,
        "features": db.features,
        "feature_mean": db.feature_mean,
        "feature_scale": db.feature_scale,
        "valid": db.valid,
        "clips": summary["clips"],
        "tags": summary["tags"],
    })
}

/// A readable text report of [`summary`].
pub fn text(db: &Database, size_bytes: Option<usize>) -> String {
    let s = summary(db, size_bytes);
    let mut out = format!(
        "frames {} ({} valid) at {} fps = {:.1} s · {} joints · {} feature dims",
        db.num_frames,
        s["num_valid_frames"],
        db.fps,
        db.duration(),
        db.num_joints(),
        db.num_features()
    );
    if let Some(b) = size_bytes {
        out += &format!(" · {:.2} MB", b as f64 / 1e6);
    }
    out += &format!(
        "\ncontacts: left {:.0}% right {:.0}% of frames\njoints: {}\n",
        100.0 * s["contact_share"][0].as_f64().unwrap_or(0.0),
        100.0 * s["contact_share"][1].as_f64().unwrap_or(0.0),
        db.skeleton.names.join(" ")
    );
    out += "sites:";
    for site in &db.skeleton.sites {
        let j = if site.joint >= 0 { db.skeleton.names[site.joint as usize].as_str() } else { "-" };
        out += &format!(" {}={}", site.name, j);
    }
    out += "\nfeatures:\n";
    for (g, f) in db.groups.iter().zip(s["features"].as_array().unwrap()) {
        out += &format!(
            "  {:<24} {:<9} {:<12} offsets {:?} weight {} dims {}..{}\n",
            g.name,
            f["kind"].as_str().unwrap_or(""),
            db.skeleton.names[g.joint],
            g.offsets,
            g.weight,
            g.first_dim,
            g.first_dim + g.num_dims
        );
    }
    out += &format!("clips ({}):\n", db.clips.len());
    for c in &db.clips {
        out += &format!(
            "  {:<28} frames {:>6}..{:<6} ({:.1} s){}\n",
            c.name,
            c.start,
            c.end,
            (c.end - c.start) as f32 / db.fps,
            if c.mirrored { " mirrored" } else { "" }
        );
    }
    out += &format!("tags ({}):\n", db.tags.len());
    for t in &db.tags {
        out += &format!(
            "  {:<12} {} frames in {} ranges\n",
            t.name,
            t.ranges.iter().map(|(s, e)| e - s).sum::<u32>(),
            t.ranges.len()
        );
    }
    out
}
