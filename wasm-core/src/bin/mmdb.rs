//! `mmdb`: build, inspect, search and benchmark motion databases from the command line.

use mmcore::config::{AutoScale, BuildConfig, Scale};
use mmcore::first_part::{self, FirstPartSpec};
use mmcore::search::{self, SearchOptions};
use mmcore::{format, inspect, limits, Bvh, Error, Source};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

const USAGE: &str = "usage:
  mmdb build (--config CONFIG.json | FILE...) -o OUT.mmdb [--fps N] [--scale S|auto] [--no-mirror]
             [--no-repair] [--json]   (FILE: .bvh, or .glb/.gltf/.vrma: each animation a clip)
  mmdb inspect DB.mmdb [--json]
  mmdb search DB.mmdb (--frame N | --query v1,v2,...) [--normalized] [-k K] [--tag TAG]
              [--beta-pose B] [--beta-trajectory B] [--exclude-radius R]
              [--method aabb|simd|scalar] [--json]   (-k > 1 lists the k best by brute force)
  mmdb dump DB.mmdb            (every array as JSON)
  mmdb bench FILE.bvh... [--json] [--seconds S]
  mmdb bench-runtime DB.mmdb [--json]   (per-character update time, characters per 4 ms)
  mmdb quality DB.mmdb [--json] [--seconds S] [--settings JSON]   (scripted inputs: distance, skating, pops)
  mmdb naturalness DB.mmdb [--json] [--seconds S] [--settings JSON]   (idle/walk/strafe/backward: style share, head pitch, hands)
  mmdb replay DB.mmdb REC.json [--alpha A] [--yaw truth|hmd|YAW.json] [--hips HIPS.json] [--settings JSON] [--json]
              (a VR recording through the tracked drive: root distance, skating, update time)
  mmdb coverage DB.mmdb OTHER.mmdb [--tag TAG] [--json]   (how well DB matches OTHER's frames: best search cost)";

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let result = match args.first().map(String::as_str) {
        Some("build") => build(&args[1..]),
        Some("inspect") => inspect_cmd(&args[1..]),
        Some("search") => search_cmd(&args[1..]),
        Some("dump") => dump(&args[1..]),
        Some("bench") => bench(&args[1..]),
        Some("bench-runtime") => bench_runtime(&args[1..]),
        Some("quality") => quality(&args[1..]),
        Some("naturalness") => naturalness(&args[1..]),
        Some("coverage") => coverage(&args[1..]),
        Some("replay") => replay(&args[1..]),
        Some("-h" | "--help" | "help") => {
            println!("{USAGE}");
            return ExitCode::SUCCESS;
        }
        _ => Err(Usage("expected a command".into()).into()),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(CliError::Usage(m)) => {
            eprintln!("mmdb: {m}\n{USAGE}");
            ExitCode::from(2)
        }
        Err(CliError::Failed(e)) => {
            eprintln!("mmdb: error: {e}");
            ExitCode::FAILURE
        }
    }
}

enum CliError {
    Usage(String),
    Failed(Error),
}
struct Usage(String);
impl From<Usage> for CliError {
    fn from(u: Usage) -> Self {
        CliError::Usage(u.0)
    }
}
impl From<Error> for CliError {
    fn from(e: Error) -> Self {
        CliError::Failed(e)
    }
}
type CliResult = Result<(), CliError>;

/// Flags and positional arguments of one command.
struct Args {
    positional: Vec<String>,
    flags: Vec<(String, Option<String>)>,
}

impl Args {
    /// `with_value` lists the flags that take a value.
    fn parse(args: &[String], with_value: &[&str], switches: &[&str]) -> Result<Args, Usage> {
        let mut out = Args { positional: Vec::new(), flags: Vec::new() };
        let mut it = args.iter();
        while let Some(a) = it.next() {
            if with_value.contains(&a.as_str()) {
                let v = it.next().ok_or_else(|| Usage(format!("{a} needs a value")))?;
                out.flags.push((a.clone(), Some(v.clone())));
            } else if switches.contains(&a.as_str()) {
                out.flags.push((a.clone(), None));
            } else if a.starts_with('-') && a.len() > 1 {
                return Err(Usage(format!("unknown option {a}")));
            } else {
                out.positional.push(a.clone());
            }
        }
        Ok(out)
    }
    fn get(&self, flag: &str) -> Option<&str> {
        self.flags.iter().rev().find(|(f, _)| f == flag).and_then(|(_, v)| v.as_deref())
    }
    fn has(&self, flag: &str) -> bool {
        self.flags.iter().any(|(f, _)| f == flag)
    }
    fn number<T: std::str::FromStr>(&self, flag: &str) -> Result<Option<T>, Usage> {
        self.get(flag).map(|v| v.parse().map_err(|_| Usage(format!("{flag}: '{v}' is not a valid number")))).transpose()
    }
}

fn read(path: &Path) -> Result<Vec<u8>, Error> {
    std::fs::read(path).map_err(|e| Error::Io(format!("{}: {e}", path.display())))
}

/// The takes of one file: a BVH file, or each animation of a glTF file (`file.glb#clip` when
/// it has several; `keep` says which of those a config asks for).
fn parse_sources(path: &Path, keep: &dyn Fn(&str) -> bool) -> Result<Vec<Source>, Error> {
    let bytes = read(path)?;
    let name = path.to_string_lossy().into_owned();
    let ext = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
    if matches!(ext.as_str(), "glb" | "gltf" | "vrma") || (ext != "bvh" && mmcore::gltf::looks_like_gltf(&bytes)) {
        let takes = mmcore::gltf::parse(&name, &bytes)?;
        let single = takes.len() == 1;
        return Ok(takes
            .into_iter()
            .map(|t| Source { name: if single { name.clone() } else { format!("{name}#{}", t.clip) }, bvh: t.bvh })
            .filter(|s| keep(&s.name))
            .collect());
    }
    Ok(vec![Source { bvh: Bvh::parse(&name, &bytes)?, name }])
}

/// Files named by a config's clip entries, relative to the config, `*`/`?` in the file name.
fn config_files(config: &BuildConfig, dir: &Path) -> Result<Vec<PathBuf>, Error> {
    let mut files: Vec<PathBuf> = Vec::new();
    for clip in &config.clips {
        let pattern = dir.join(mmcore::config::split_clip(&clip.file).0);
        let name = pattern.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        let parent = pattern.parent().unwrap_or(dir);
        let mut matched: Vec<PathBuf> = if name.contains(['*', '?']) {
            let entries = std::fs::read_dir(parent).map_err(|e| Error::Io(format!("{}: {e}", parent.display())))?;
            entries
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.file_name().is_some_and(|n| mmcore::config::wildcard_match(&name, &n.to_string_lossy())))
                .collect()
        } else {
            vec![pattern.clone()]
        };
        if matched.is_empty() {
            return Err(Error::config(format!(
                "clip file pattern '{}' matches no file in {}",
                clip.file,
                parent.display()
            )));
        }
        matched.sort();
        for m in matched {
            if !files.contains(&m) {
                files.push(m);
            }
        }
    }
    Ok(files)
}

/// `OUT.first.mmdb` beside `OUT.mmdb`: the first part `spec` asks for, naming the whole by its
/// file name and checksum (the header's, read from the bytes just written).
fn write_first_part(output: &str, bytes: &[u8], whole: &mmcore::Database, spec: &FirstPartSpec) -> CliResult {
    let path = Path::new(output);
    let name = path.file_name().and_then(|n| n.to_str()).ok_or_else(|| Usage(format!("-o {output}: no file name")))?;
    let checksum = u32::from_le_bytes(bytes[24..28].try_into().expect("a written file has a header"));
    let clips = first_part::choose(whole, spec)?;
    let part = first_part::cut(whole, &clips, name, checksum)?;
    let part_bytes = format::to_bytes(&part);
    let stem = name.strip_suffix(".mmdb").unwrap_or(name);
    let part_path = path.with_file_name(format!("{stem}.first.mmdb"));
    std::fs::write(&part_path, &part_bytes).map_err(|e| Error::Io(format!("{}: {e}", part_path.display())))?;
    println!(
        "{}: first part, {} of {} clips, {} frames ({:.1} s), {:.2} MB",
        part_path.display(),
        part.clips.len(),
        whole.clips.len(),
        part.num_frames,
        part.duration(),
        part_bytes.len() as f64 / 1e6
    );
    Ok(())
}

fn build(args: &[String]) -> CliResult {
    let a = Args::parse(
        args,
        &["-o", "--output", "--config", "--fps", "--scale"],
        &["--no-mirror", "--no-repair", "--json"],
    )?;
    let output = a.get("-o").or(a.get("--output")).ok_or_else(|| Usage("build needs -o OUT.mmdb".into()))?;
    let (mut config, files) = match a.get("--config") {
        Some(path) => {
            let path = Path::new(path);
            let text = String::from_utf8_lossy(&read(path)?).into_owned();
            let config = BuildConfig::from_json(&text).map_err(|e| match e {
                Error::Config(m) => Error::Config(format!("{}: {m}", path.display())),
                e => e,
            })?;
            let dir = path.parent().unwrap_or(Path::new("."));
            let mut config = config;
            if let Some(csv) = &config.frame_cuts {
                let csv_path = dir.join(csv);
                let text = String::from_utf8_lossy(&read(&csv_path)?).into_owned();
                config.cuts = mmcore::frame_cuts::parse(&text).map_err(|e| match e {
                    Error::Config(m) => Error::Config(format!("{}: {m}", csv_path.display())),
                    e => e,
                })?;
            }
            let files = config_files(&config, dir)?;
            (config, files)
        }
        None => (BuildConfig::default(), a.positional.iter().map(PathBuf::from).collect()),
    };
    if files.is_empty() {
        return Err(Usage("build needs BVH/glTF files or --config".into()).into());
    }
    // Range-checked here, by flag name: the config was validated before these override it.
    if let Some(fps) = a.number::<f64>("--fps")? {
        limits::check_fps(fps).map_err(|m| Usage(format!("--fps: {m}")))?;
        config.fps = fps;
    }
    if let Some(s) = a.get("--scale") {
        config.scale = if s == "auto" {
            Scale::Auto(AutoScale::Auto)
        } else {
            let v: f64 =
                s.parse().map_err(|_| Usage(format!("--scale: '{}' is not a number or 'auto'", limits::quote(s))))?;
            limits::check_scale(v).map_err(|m| Usage(format!("--scale: {m}")))?;
            Scale::Fixed(v)
        };
    }
    if a.has("--no-repair") {
        config.repair_spikes = false;
    }
    if a.has("--no-mirror") {
        config.mirror = false;
        config.clips.iter_mut().for_each(|c| c.mirror = Some(false));
    }
    let started = Instant::now();
    let from_config = a.get("--config").is_some();
    let keep = |name: &str| !from_config || config.clip_spec(name).is_some();
    let sources = files
        .iter()
        .map(|f| parse_sources(f, &keep))
        .collect::<Result<Vec<_>, _>>()?
        .into_iter()
        .flatten()
        .collect::<Vec<_>>();
    let parsed = started.elapsed();
    let out = mmcore::build(&config, &sources)?;
    let bytes = format::to_bytes(&out.database);
    if let Some(dir) = Path::new(output).parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| Error::Io(format!("{}: {e}", dir.display())))?;
    }
    std::fs::write(output, &bytes).map_err(|e| Error::Io(format!("{output}: {e}")))?;
    if let Some(spec) = &config.first_part {
        write_first_part(output, &bytes, &out.database, spec)?;
    }
    for w in &out.warnings {
        eprintln!("mmdb: warning: {w}");
    }
    for note in out.retarget_notes() {
        eprintln!("mmdb: {note}");
    }
    let db = &out.database;
    if a.has("--json") {
        println!("{}", inspect::summary(db, Some(bytes.len())));
    } else {
        println!(
            "{output}: {} files{} → {} clips, {} frames at {} fps ({:.1} s), {} joints, {} features, {:.2} MB in {:.2} s (parse {:.2} s)",
            files.len(),
            if sources.len() == files.len() { String::new() } else { format!(" ({} takes)", sources.len()) },
            db.clips.len(),
            db.num_frames,
            db.fps,
            db.duration(),
            db.num_joints(),
            db.num_features(),
            bytes.len() as f64 / 1e6,
            started.elapsed().as_secs_f64(),
            parsed.as_secs_f64()
        );
    }
    Ok(())
}

fn load(path: &str) -> Result<(mmcore::Database, usize), Error> {
    let bytes = read(Path::new(path))?;
    let db = format::from_bytes(&bytes).map_err(|e| match e {
        Error::Format(m) => Error::Format(format!("{path}: {m}")),
        e => e,
    })?;
    Ok((db, bytes.len()))
}

fn inspect_cmd(args: &[String]) -> CliResult {
    let a = Args::parse(args, &[], &["--json"])?;
    let [path] = a.positional.as_slice() else { return Err(Usage("inspect needs one .mmdb file".into()).into()) };
    let (db, size) = load(path)?;
    if a.has("--json") {
        println!("{}", serde_json::to_string_pretty(&inspect::summary(&db, Some(size))).unwrap());
    } else {
        print!("{path}\n{}", inspect::text(&db, Some(size)));
    }
    Ok(())
}

fn dump(args: &[String]) -> CliResult {
    let a = Args::parse(args, &[], &[])?;
    let [path] = a.positional.as_slice() else { return Err(Usage("dump needs one .mmdb file".into()).into()) };
    println!("{}", inspect::dump(&load(path)?.0));
    Ok(())
}

fn search_cmd(args: &[String]) -> CliResult {
    let a = Args::parse(
        args,
        &["--frame", "--query", "-k", "--tag", "--beta-pose", "--beta-trajectory", "--exclude-radius", "--method"],
        &["--normalized", "--json"],
    )?;
    let [path] = a.positional.as_slice() else { return Err(Usage("search needs one .mmdb file".into()).into()) };
    let (db, _) = load(path)?;
    // Clamped to the database: a huge radius or k would overflow `f + radius + 1` or reserve
    // k result slots.
    let radius = a.number::<usize>("--exclude-radius")?.unwrap_or(20).min(db.num_frames);
    let (query, exclude) = match (a.number::<usize>("--frame")?, a.get("--query")) {
        (Some(f), None) => {
            if f >= db.num_frames {
                return Err(
                    Usage(format!("--frame {f} is out of range (database has {} frames)", db.num_frames)).into()
                );
            }
            (db.feature(f).to_vec(), Some((f.saturating_sub(radius), f + radius + 1)))
        }
        (None, Some(q)) => {
            let values = q
                .split(',')
                .map(|v| v.trim().parse::<f32>())
                .collect::<Result<Vec<_>, _>>()
                .map_err(|_| Usage(format!("--query: '{q}' is not a comma-separated list of numbers")))?;
            if values.len() != db.num_features() {
                return Err(Usage(format!(
                    "--query has {} values, the database has {} feature dims",
                    values.len(),
                    db.num_features()
                ))
                .into());
            }
            (if a.has("--normalized") { values } else { search::normalize_query(&db, &values) }, None)
        }
        _ => return Err(Usage("search needs exactly one of --frame N or --query".into()).into()),
    };
    let mask = match a.get("--tag") {
        Some(t) => Some(db.tag_mask(t).ok_or_else(|| {
            Error::config(format!(
                "no tag '{t}' (tags: {})",
                db.tags.iter().map(|t| t.name.as_str()).collect::<Vec<_>>().join(", ")
            ))
        })?),
        None => None,
    };
    let beta = |flag: &str| -> Result<f32, Usage> {
        let b = a.number::<f32>(flag)?.unwrap_or(1.0);
        if !(0.0..=1e6).contains(&b) {
            return Err(Usage(format!("{flag}: must be 0 to 1e6, found {b}")));
        }
        Ok(b)
    };
    let options = SearchOptions {
        beta_pose: beta("--beta-pose")?,
        beta_trajectory: beta("--beta-trajectory")?,
        exclude,
        mask: mask.as_deref(),
        ..Default::default()
    };
    let k = a.number::<usize>("-k")?.unwrap_or(1).clamp(1, db.num_frames);
    let method = match a.get("--method").unwrap_or("aabb") {
        "aabb" => search::SearchMethod::Aabb,
        "simd" => search::SearchMethod::Simd,
        "scalar" => search::SearchMethod::Scalar,
        m => return Err(Usage(format!("--method: '{m}' is not aabb, simd or scalar")).into()),
    };
    let (best, elapsed, method_name) = if k == 1 {
        let index = search::SearchIndex::new(&db)?;
        let started = Instant::now();
        let best: Vec<(usize, f32)> = index.search(method, &query, &options, f32::INFINITY).into_iter().collect();
        (best, started.elapsed().as_secs_f64() * 1e3, method.name())
    } else {
        let started = Instant::now();
        let best = search::brute_force(&db, &query, &options, k);
        (best, started.elapsed().as_secs_f64() * 1e3, "brute_force")
    };
    let results: Vec<serde_json::Value> = best
        .iter()
        .map(|&(f, cost)| {
            let c = &db.clips[db.clip_at(f)];
            serde_json::json!({"frame": f, "cost": cost, "clip": c.name, "clip_frame": f as u32 - c.start})
        })
        .collect();
    if a.has("--json") {
        println!("{}", serde_json::json!({"method": method_name, "ms": elapsed, "results": results}));
    } else {
        println!("{method_name} search over {} frames in {elapsed:.4} ms", db.num_frames);
        for r in &results {
            println!(
                "  frame {:>6}  cost {:>10.4}  {} +{}",
                r["frame"],
                r["cost"].as_f64().unwrap(),
                r["clip"].as_str().unwrap(),
                r["clip_frame"]
            );
        }
    }
    Ok(())
}

/// Median of repeated timings of `f`, run for about `seconds`.
fn median_seconds(seconds: f64, mut f: impl FnMut()) -> (f64, usize) {
    let mut times = Vec::new();
    let started = Instant::now();
    while times.len() < 3 || (started.elapsed().as_secs_f64() < seconds && times.len() < 1000) {
        let t = Instant::now();
        f();
        times.push(t.elapsed().as_secs_f64());
    }
    times.sort_by(f64::total_cmp);
    (times[times.len() / 2], times.len())
}

fn bench(args: &[String]) -> CliResult {
    let a = Args::parse(args, &["--seconds"], &["--json"])?;
    if a.positional.is_empty() {
        return Err(Usage("bench needs BVH files".into()).into());
    }
    let seconds = a.number::<f64>("--seconds")?.unwrap_or(2.0);
    if !(0.0..=3600.0).contains(&seconds) {
        return Err(Usage(format!("--seconds: must be 0 to 3600, found {seconds}")).into());
    }
    let files: Vec<(String, Vec<u8>)> =
        a.positional.iter().map(|p| read(Path::new(p)).map(|b| (p.clone(), b))).collect::<Result<_, _>>()?;
    let megabytes = files.iter().map(|(_, b)| b.len()).sum::<usize>() as f64 / 1e6;
    // Parse and build once outside the clock: a bad file is an error, not a panic mid-timing.
    let sources: Vec<Source> = files
        .iter()
        .map(|(n, b)| Bvh::parse(n, b).map(|bvh| Source { name: n.clone(), bvh }))
        .collect::<Result<_, _>>()?;
    let config = BuildConfig::default();
    let mut output_frames = mmcore::build(&config, &sources)?.database.num_frames;
    let (parse, parse_runs) = median_seconds(seconds, || {
        for (name, bytes) in &files {
            let _ = std::hint::black_box(Bvh::parse(name, bytes));
        }
    });
    let source_frames: usize = sources.iter().map(|s| s.bvh.num_frames).sum();
    let (build, build_runs) = median_seconds(seconds, || {
        if let Ok(out) = mmcore::build(&config, &sources) {
            output_frames = out.database.num_frames;
            std::hint::black_box(format::to_bytes(&out.database));
        }
    });
    let result = serde_json::json!({
        "runtime": "native",
        "files": files.len(),
        "megabytes": megabytes,
        "parse_ms": parse * 1e3,
        "parse_mb_per_s": megabytes / parse,
        "parse_runs": parse_runs,
        "source_frames": source_frames,
        "database_frames": output_frames,
        "build_ms": build * 1e3,
        "build_source_frames_per_s": source_frames as f64 / build,
        "build_database_frames_per_s": output_frames as f64 / build,
        "build_runs": build_runs,
    });
    if a.has("--json") {
        println!("{result}");
    } else {
        println!(
            "native: parse {megabytes:.1} MB in {:.1} ms = {:.0} MB/s; build {source_frames} source frames → {output_frames} database frames in {:.1} ms = {:.0} source frames/s (medians of {parse_runs}/{build_runs} runs)",
            parse * 1e3,
            megabytes / parse,
            build * 1e3,
            source_frames as f64 / build
        );
    }
    Ok(())
}

/// Per-character update cost (one character following a zig-zag with runs and stops) and
/// how many characters fit in a 4 ms budget (a crowd of 256, per-character cost × 256).
fn bench_runtime(args: &[String]) -> CliResult {
    use mmcore::character::CharacterSettings;
    use mmcore::controller::Input;
    let a = Args::parse(args, &[], &["--json"])?;
    let [path] = a.positional.as_slice() else { return Err(Usage("bench-runtime needs one .mmdb file".into()).into()) };
    let (db, _) = load(path)?;
    let index = mmcore::search::SearchIndex::new(&db)?;
    let input = |step: usize| {
        let t = step as f32 / 60.0;
        let phase = (t / 2.0) as usize % 4;
        Input {
            direction: [
                glam::Vec2::new(0.7, 0.7),
                glam::Vec2::new(-0.7, 0.7),
                glam::Vec2::new(0.0, -1.0),
                glam::Vec2::ZERO,
            ][phase],
            run: phase == 2,
            ..Default::default()
        }
    };
    let mut crowd = mmcore::crowd::Crowd::new(&db, 1, &CharacterSettings::default(), db.toe_height_in_contact())
        .map_err(mmcore::Error::config)?;
    let mut times = Vec::with_capacity(3600);
    for step in 0..3600 {
        crowd.inputs[0] = input(step);
        let t = Instant::now();
        crowd.update(&db, &index, 1.0 / 60.0);
        times.push(t.elapsed().as_secs_f64() * 1e3);
    }
    times.sort_by(f64::total_cmp);
    let (median, p95) = (times[times.len() / 2], times[times.len() * 95 / 100]);
    let n = mmcore::crowd::Crowd::max_characters(&db).min(256);
    let mut crowd = mmcore::crowd::Crowd::new(&db, n, &CharacterSettings::default(), db.toe_height_in_contact())
        .map_err(mmcore::Error::config)?;
    let mut crowd_times = Vec::new();
    // Timed after 120 steps, as in the browser's benchmark (web/src/bench/runtime-bench.ts): a
    // block of frames' velocities is derived the first time a character plays one of them, once
    // per database — not the crowd's steady state.
    for step in 0..120 + 240 {
        for (i, inp) in crowd.inputs.iter_mut().enumerate() {
            *inp = input(step + 37 * i);
        }
        let t = Instant::now();
        crowd.update(&db, &index, 1.0 / 60.0);
        if step >= 120 {
            crowd_times.push(t.elapsed().as_secs_f64() * 1e3);
        }
    }
    crowd_times.sort_by(f64::total_cmp);
    let per_character = crowd_times[crowd_times.len() / 2] / n as f64;
    let result = serde_json::json!({
        "runtime": "native",
        "database_frames": db.num_frames,
        "update_ms_median": median,
        "update_ms_p95": p95,
        "crowd_ms_per_character": per_character,
        "characters_in_4ms": (4.0 / per_character).floor(),
    });
    if a.has("--json") {
        println!("{result}");
    } else {
        println!(
            "native: update median {median:.4} ms, p95 {p95:.4} ms; crowd of {n}: {per_character:.4} ms per character → {} characters in 4 ms",
            (4.0 / per_character).floor()
        );
    }
    Ok(())
}

/// What the scripted harnesses (`quality`, `naturalness`) take: one database, `--seconds` (60)
/// per script, `--settings` over the defaults, `--json`.
struct Scripted {
    path: String,
    db: mmcore::Database,
    seconds: f32,
    settings: mmcore::character::CharacterSettings,
    json: bool,
}

fn scripted(args: &[String], command: &str) -> Result<Scripted, CliError> {
    let a = Args::parse(args, &["--seconds", "--settings"], &["--json"])?;
    let [path] = a.positional.as_slice() else { return Err(Usage(format!("{command} needs one .mmdb file")).into()) };
    let (db, _) = load(path)?;
    let seconds = a.number::<f32>("--seconds")?.unwrap_or(60.0);
    if !(seconds > 0.0 && seconds <= 3600.0) {
        return Err(Usage(format!("--seconds: must be more than 0 and at most 3600, found {seconds}")).into());
    }
    let defaults = mmcore::character::CharacterSettings::default();
    let settings = match a.get("--settings") {
        Some(json) => defaults.patched(json).map_err(Usage)?,
        None => defaults,
    };
    Ok(Scripted { path: path.clone(), db, seconds, settings, json: a.has("--json") })
}

/// The quality harness: each scripted input for `--seconds` (60) at 60 Hz.
fn quality(args: &[String]) -> CliResult {
    use mmcore::quality;
    let Scripted { path, db, seconds, settings, json } = scripted(args, "quality")?;
    let reports: Vec<quality::Report> =
        quality::scripts().iter().map(|s| quality::run(&db, &settings, s, seconds, 1.0 / 60.0)).collect();
    if json {
        println!("{}", serde_json::to_string_pretty(&reports).unwrap());
    } else {
        print!(
            "{path}: {seconds} s per script at 60 Hz, α = {} m\n{}",
            settings.clamp_distance,
            quality::table(&reports)
        );
    }
    Ok(())
}

/// The naturalness harness: standing, walking, side-stepping, walking backward (style share,
/// head pitch, hands).
fn naturalness(args: &[String]) -> CliResult {
    use mmcore::naturalness;
    let Scripted { path, db, seconds, settings, json } = scripted(args, "naturalness")?;
    let reports = naturalness::Motion::ALL
        .iter()
        .map(|&m| naturalness::measure(&db, &settings, m, seconds, 1.0 / 60.0))
        .collect::<Result<Vec<_>, String>>()
        .map_err(|e| CliError::Failed(Error::config(e)))?;
    if json {
        println!("{}", serde_json::to_string_pretty(&reports).unwrap());
    } else {
        print!(
            "{path}: {seconds} s per motion at 60 Hz, style '{}' (bias {})\n{}",
            settings.style,
            settings.style_bias,
            naturalness::table(&reports)
        );
    }
    Ok(())
}

fn coverage(args: &[String]) -> CliResult {
    use mmcore::quality;
    let a = Args::parse(args, &["--tag"], &["--json"])?;
    let [path, other_path] = a.positional.as_slice() else {
        return Err(Usage("coverage needs DB.mmdb and OTHER.mmdb".into()).into());
    };
    let (db, _) = load(path)?;
    let (other, _) = load(other_path)?;
    let mask = match a.get("--tag") {
        Some(t) => Some(other.tag_mask(t).ok_or_else(|| Usage(format!("{other_path} has no tag '{t}'")))?),
        None => None,
    };
    let costs = quality::coverage(&db, &other, mask.as_deref()).map_err(Error::config)?;
    let c = quality::summarize(&costs);
    if a.has("--json") {
        println!("{}", serde_json::json!({"frames": costs.len(), "mean": c.0, "median": c.1, "p90": c.2}));
    } else {
        println!(
            "{path} on {} frames of {other_path}: best cost mean {:.3}, median {:.3}, p90 {:.3}",
            costs.len(),
            c.0,
            c.1,
            c.2
        );
    }
    Ok(())
}

fn replay(args: &[String]) -> CliResult {
    use mmcore::recording::Recording;
    use mmcore::vr_replay;
    let a = Args::parse(args, &["--alpha", "--yaw", "--hips", "--settings"], &["--json"])?;
    let [path, rec_path] = a.positional.as_slice() else {
        return Err(Usage("replay needs DB.mmdb and REC.json".into()).into());
    };
    let (db, _) = load(path)?;
    let text = String::from_utf8_lossy(&read(Path::new(rec_path))?).into_owned();
    let rec = Recording::from_json(&text).map_err(|e| Error::config(format!("{rec_path}: {e}")))?;
    if rec.num_frames() < 2 {
        return Err(Error::config(format!(
            "{rec_path}: a replay needs at least 2 frames, the recording has {}",
            rec.num_frames()
        ))
        .into());
    }
    let alpha = a.number::<f32>("--alpha")?.unwrap_or(0.3);
    if !(alpha > 0.0 && alpha <= 10.0) {
        return Err(Usage(format!("--alpha: must be more than 0 and at most 10 m, found {alpha}")).into());
    }
    let n = rec.num_frames();
    let yaw: Vec<f32> = match a.get("--yaw").unwrap_or("truth") {
        "truth" => rec
            .truth_yaw
            .clone()
            .ok_or_else(|| Usage(format!("{rec_path} has no truth.bodyYaw: use --yaw hmd or a file")))?,
        "hmd" => rec.head_rotation.iter().map(|&q| vr_replay::heading_yaw(q)).collect(),
        file => {
            let v: Vec<f32> =
                serde_json::from_slice(&read(Path::new(file))?).map_err(|e| Error::config(format!("{file}: {e}")))?;
            if v.len() != n {
                return Err(Usage(format!("{file}: {} yaws for {n} frames", v.len())).into());
            }
            v
        }
    };
    // Where the network puts the hips, per frame: [x, z] room metres from the head centre, or
    // null (the head centre itself).
    let hips: Option<Vec<glam::Vec2>> = match a.get("--hips") {
        None => None,
        Some(file) => {
            let v: Vec<Option<[f32; 2]>> =
                serde_json::from_slice(&read(Path::new(file))?).map_err(|e| Error::config(format!("{file}: {e}")))?;
            if v.len() != n {
                return Err(Usage(format!("{file}: {} hips offsets for {n} frames", v.len())).into());
            }
            Some(v.into_iter().map(|h| h.map_or(glam::Vec2::NAN, glam::Vec2::from)).collect())
        }
    };
    let settings = match a.get("--settings") {
        Some(json) => vr_replay::vr_settings().patched(json).map_err(Usage)?,
        None => vr_replay::vr_settings(),
    };
    let index = mmcore::search::SearchIndex::new(&db)?;
    let r = vr_replay::replay(&db, &index, &rec, &yaw, hips.as_deref(), alpha, &settings);
    if a.has("--json") {
        println!("{}", serde_json::to_string(&r).unwrap());
    } else {
        let d = r.root_distance.map_or("-".into(), |d| format!("{:.1} / {:.1}", 100.0 * d.mean, 100.0 * d.p95));
        let body = match r.hips_distance {
            Some(h) => format!(
                " ({} driven by the tracked body: hips {:.1} cm mean from the tracked hips)",
                r.body_frames,
                100.0 * h.mean
            ),
            None => String::new(),
        };
        println!(
            "{rec_path}: {} frames{body}, {:.1} s, α {} m: root distance cm mean/p95 {d}, gap mean {:.1} cm ({:.0}% clamped), skating {:.1} cm/s (legacy toe-height measure {:.1}), update ms median/p95 {:.4} / {:.4}",
            r.frames,
            r.seconds,
            r.alpha,
            100.0 * r.head_gap.mean,
            100.0 * r.clamped_share,
            r.skating,
            r.skating_toe_height,
            r.update_ms.median,
            r.update_ms.p95
        );
    }
    Ok(())
}
