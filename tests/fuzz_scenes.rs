//! A mutation fuzzer for scene files: the project's scenes mutated the way hostile input is
//! (extreme and non-finite numbers, wrong types, deleted and unknown fields, odd names and paths,
//! flipped bytes, truncations), each parsed and validated, and when valid and small enough, its
//! garments built and stepped for a frame, and now and then baked whole into a temporary folder.
//!
//! The property: nothing panics, every error is bad input (exit code 2) or a failure while running
//! (1), and a scene that validates either steps to finite positions or says it became unstable.
//!
//! `cargo test --test fuzz_scenes` runs a short campaign (a few hundred cases, seconds). The long
//! one: `DRAPE_FUZZ_SECONDS=3600 cargo test --release --test fuzz_scenes -- --nocapture`, which
//! prints what it tried and writes each finding to `target/fuzz-findings/`.

use drape::scene::Scene;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// SplitMix64: the campaign is reproducible from its seed.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
    fn pick<'a, T>(&mut self, items: &'a [T]) -> &'a T {
        &items[self.below(items.len())]
    }
}

const NUMBERS: [f64; 22] = [
    0.0,
    -0.0,
    -1.0,
    1.0,
    0.5,
    2.0,
    1e-30,
    1e-7,
    1e30,
    1e39,
    -1e39,
    1e300,
    4294967295.0,
    4294967296.0,
    2147483648.0,
    -2147483649.0,
    65536.0,
    1e6,
    3.0,
    100.0,
    0.999,
    1.5,
];

const STRINGS: [&str; 16] = [
    "",
    ".",
    "..",
    "../../x",
    "/dev/zero",
    "/",
    "a\u{0}b",
    "%04d",
    "%d.obj",
    "rbgs",
    "sheet",
    "rope",
    "mesh",
    "top_edge",
    "\u{feff}",
    "ünïcödé",
];

/// Every node's JSON pointer, to pick one to mutate.
fn pointers(v: &Value, at: String, out: &mut Vec<String>) {
    out.push(at.clone());
    match v {
        Value::Object(m) => m
            .iter()
            .for_each(|(k, c)| pointers(c, format!("{at}/{k}"), out)),
        Value::Array(a) => a
            .iter()
            .enumerate()
            .for_each(|(i, c)| pointers(c, format!("{at}/{i}"), out)),
        _ => {}
    }
}

/// A value of another kind than JSON scenes expect there.
fn odd_value(rng: &mut Rng) -> Value {
    match rng.below(8) {
        0 => Value::Null,
        1 => Value::Bool(rng.below(2) == 0),
        2 => Value::String(rng.pick(&STRINGS).to_string()),
        3 => Value::Array(vec![]),
        4 => Value::Object(Default::default()),
        5 => serde_json::json!([rng.pick(&NUMBERS), rng.pick(&NUMBERS)]),
        6 => Value::String("x".repeat(300)),
        _ => serde_json::json!(rng.pick(&NUMBERS)),
    }
}

/// One structural mutation of a scene.
fn mutate_value(scene: &mut Value, rng: &mut Rng) {
    let mut all = Vec::new();
    pointers(scene, String::new(), &mut all);
    let at = rng.pick(&all).clone();
    let Some(node) = scene.pointer_mut(&at) else {
        return;
    };
    match rng.below(9) {
        // A plausible edit: a number scaled or negated (most of these still validate).
        7 | 8 if node.is_number() => {
            let n = node.as_f64().unwrap_or(0.0) * rng.pick(&[0.5, 2.0, 10.0, 0.1, -1.0, 100.0]);
            *node = serde_json::Number::from_f64(n).map_or(Value::Null, Value::Number);
        }
        // The commonest hostile input: an extreme number where a number goes.
        0..=2 if node.is_number() || rng.below(3) == 0 => {
            let n = *rng.pick(&NUMBERS);
            *node = serde_json::Number::from_f64(n).map_or(Value::Null, Value::Number);
        }
        3 => *node = odd_value(rng),
        4 => match node {
            Value::Object(m) if !m.is_empty() => {
                let key = m.keys().nth(rng.below(m.len())).unwrap().clone();
                m.remove(&key);
            }
            Value::Array(a) if !a.is_empty() => {
                let item = a[rng.below(a.len())].clone();
                for _ in 0..1 + rng.below(3) {
                    a.push(item.clone());
                }
            }
            _ => *node = odd_value(rng),
        },
        5 => {
            if let Value::Object(m) = node {
                let key = *rng.pick(&["name", "frames", "radius", "size", "pins", "kind", "zzz"]);
                m.insert(key.to_string(), odd_value(rng));
            } else {
                *node = Value::String(rng.pick(&STRINGS).to_string());
            }
        }
        _ => {
            if let Value::String(s) = node {
                *s = rng.pick(&STRINGS).to_string();
            } else {
                *node = odd_value(rng);
            }
        }
    }
}

/// One text-level mutation: a flipped byte, a truncation, or an inserted character.
fn mutate_text(text: &str, rng: &mut Rng) -> String {
    let mut bytes = text.as_bytes().to_vec();
    if bytes.is_empty() {
        return String::new();
    }
    match rng.below(3) {
        0 => {
            let i = rng.below(bytes.len());
            bytes[i] ^= 1 << rng.below(8);
        }
        1 => bytes.truncate(rng.below(bytes.len())),
        _ => {
            let i = rng.below(bytes.len());
            bytes.insert(i, *rng.pick(b"{}[],:\"0-e.9\\ "));
        }
    }
    String::from_utf8_lossy(&bytes).into_owned()
}

/// What one case did.
#[derive(Default)]
struct Tally {
    cases: usize,
    rejected: usize,
    stepped: usize,
    baked: usize,
    unstable: usize,
    findings: Vec<String>,
    /// How often each field was named by a refusal.
    refused_fields: std::collections::BTreeMap<String, usize>,
}

impl Tally {
    fn refuse(&mut self, e: &drape::Error) {
        self.rejected += 1;
        let field = match e {
            drape::Error::SceneSyntax { path, .. } => format!("syntax at {path}"),
            drape::Error::InvalidField { field, .. } => field.clone(),
            other => other.to_string(),
        };
        // Indices make every garment its own row: fold them.
        let folded: String = field
            .split('[')
            .map(|p| {
                p.split_once(']')
                    .map_or(p.to_string(), |(_, rest)| format!("[]{rest}"))
            })
            .collect();
        *self.refused_fields.entry(folded).or_default() += 1;
    }
}

/// Particle-iterations of one frame of a (validated) scene's sheets and ropes.
fn frame_work(scene: &Scene) -> f64 {
    let particles: f64 = scene
        .garments
        .iter()
        .map(|g| match g.kind {
            // Unknown until the mesh is voxelized: at most the lattice limit.
            drape::scene::GarmentKind::Mesh => 0.0,
            _ => g.resolution.iter().map(|&n| n as f64).product(),
        })
        .sum();
    particles
        * scene.substeps_per_frame() as f64
        * scene.solver.iterations as f64
        * scene.solver.inner_iterations as f64
}

/// Runs one mutated scene text through parse, validation, a step and sometimes a bake.
fn exercise(text: &str, base: &Path, bake_it: bool, tally: &mut Tally) -> Result<(), String> {
    tally.cases += 1;
    let scene = match Scene::parse_in(text, "fuzz.json", base) {
        Ok(s) => s,
        Err(e) => {
            if e.exit_code() != 2 {
                return Err(format!("parse error with exit code {}: {e}", e.exit_code()));
            }
            tally.refuse(&e);
            return Ok(());
        }
    };
    // Characters cost a second to import: the bake path exercises them, the step skips them.
    if frame_work(&scene) > 2e6 {
        return Ok(());
    }
    let garments = match drape::garment::build_all(&scene, "fuzz.json") {
        Ok(g) => g,
        Err(e) => {
            tally.refuse(&e);
            return (e.exit_code() == 2)
                .then_some(())
                .ok_or_else(|| e.to_string());
        }
    };
    // Mesh garments' lattices are known now.
    let particles: usize = garments.iter().map(|g| g.particle_count()).sum();
    let work = particles as f64
        * scene.substeps_per_frame() as f64
        * scene.solver.iterations as f64
        * scene.solver.inner_iterations as f64;
    if work > 2e6 {
        return Ok(());
    }
    let mut sim = drape::sim::Simulation::from_garments(&scene, &garments, scene.solver.clone());
    sim.step_frame();
    tally.stepped += 1;
    if !sim.state.is_finite() {
        tally.unstable += 1;
    }
    if bake_it {
        let dir = tempfile::tempdir().map_err(|e| e.to_string())?;
        let mut small = scene.clone();
        small.frames = small.frames.min(2);
        small.backend = drape::scene::BackendKind::Cpu;
        small.output.preview = false;
        let options = drape::bake::BakeOptions {
            out: dir.path().join("out"),
            scene_file: "fuzz.json".into(),
            threads: Some(1),
            progress: drape::bake::ProgressView::Hidden,
            shell_cache: Some(dir.path().join("cache")),
            resume: Default::default(),
            until: None,
            fixed_team: false,
        };
        match drape::bake::bake(&small, &options) {
            Ok(b) => {
                tally.baked += 1;
                if !b.report.stable {
                    tally.unstable += 1;
                } else if b.positions.iter().any(|p| !p.is_finite()) {
                    return Err("a stable bake with non-finite positions".into());
                }
            }
            Err(e) if e.exit_code() == 2 => tally.refuse(&e),
            Err(e) => {
                // Failures while running are allowed (exit 1), but must not leave files.
                if std::fs::read_dir(dir.path())
                    .map_err(|e| e.to_string())?
                    .any(|e| e.is_ok_and(|e| e.file_name() != "cache"))
                {
                    return Err(format!("a failed bake left files: {e}"));
                }
            }
        }
    }
    Ok(())
}

fn seeds() -> Vec<(String, PathBuf)> {
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut out: Vec<(String, PathBuf)> = std::fs::read_dir(&scenes)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "json"))
        .map(|p| (std::fs::read_to_string(&p).unwrap(), scenes.clone()))
        .collect();
    out.sort();
    out.push((
        r#"{ "frames": 2, "garments": [{ "kind": "rope", "resolution": [8], "pins": [[0]] }] }"#
            .into(),
        scenes.clone(),
    ));
    out.push((
        r#"{ "frames": 3, "checkpoint_every": 1, "accuracy": { "max_strain": 0.2, "max_penetration": 0.01 },
             "forces": [{ "kind": "attractor", "position": [0, 0.5, 0], "strength": 2, "radius": 1 }],
             "garments": [{ "resolution": [8, 8], "pins": [[0, 0]] }] }"#
            .into(),
        scenes.clone(),
    ));
    out.push((
        r#"{ "frames": 2, "colliders": [{ "kind": "sphere", "centre": [0, 0.5, 0], "radius": 0.2 }],
             "garments": [{ "resolution": [8, 8], "attachments": [{ "particles": "corners",
             "keyframes": [{ "time": 0 }, { "time": 1, "translation": [0, 1, 0] }] }] }] }"#
            .into(),
        scenes,
    ));
    out
}

/// Runs the campaign for `budget`, or `cases` cases, whichever ends first.
fn campaign(seed: u64, budget: Duration, cases: usize) -> Tally {
    let seeds = seeds();
    let mut rng = Rng(seed);
    let mut tally = Tally::default();
    let start = Instant::now();
    let findings = Path::new(env!("CARGO_MANIFEST_DIR")).join("target/fuzz-findings");
    std::panic::set_hook(Box::new(|_| {}));
    while tally.cases < cases && start.elapsed() < budget {
        let (text, base) = rng.pick(&seeds).clone();
        // Mostly one structural change, so most cases still parse and reach the solver.
        let mutated = if rng.below(8) == 0 {
            mutate_text(&text, &mut rng)
        } else {
            let mut v: Value = serde_json::from_str(&text).unwrap();
            for _ in 0..1 + rng.below(4) / 3 {
                mutate_value(&mut v, &mut rng);
            }
            v.to_string()
        };
        let bake_it = rng.below(40) == 0;
        // The case in flight, so a hang can be looked at.
        let _ = std::fs::create_dir_all(&findings);
        let _ = std::fs::write(findings.join("current.json"), &mutated);
        let case_start = Instant::now();
        let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            exercise(&mutated, &base, bake_it, &mut tally)
        }));
        let finding = match result {
            Ok(Ok(())) => None,
            Ok(Err(why)) => Some(why),
            Err(panic) => Some(format!(
                "panic: {}",
                panic
                    .downcast_ref::<String>()
                    .cloned()
                    .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                    .unwrap_or_default()
            )),
        };
        let slow = case_start.elapsed() > Duration::from_secs(30);
        if let Some(why) = finding.or_else(|| slow.then(|| "took over 30 s".to_string())) {
            let _ = std::fs::create_dir_all(&findings);
            let file = findings.join(format!("case-{seed}-{}.json", tally.cases));
            let _ = std::fs::write(&file, &mutated);
            tally.findings.push(format!("{why} ({})", file.display()));
        }
    }
    let _ = std::panic::take_hook();
    let _ = std::fs::remove_file(findings.join("current.json"));
    tally
}

/// Replays the scene files in `dir` (findings of a campaign) through the same checks.
fn replay(dir: &Path) -> Tally {
    let base = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut tally = Tally::default();
    std::panic::set_hook(Box::new(|_| {}));
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "json"))
        .collect();
    files.sort();
    for file in files {
        let text = std::fs::read_to_string(&file).unwrap();
        let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            exercise(&text, &base, true, &mut tally)
        }));
        match result {
            Ok(Ok(())) => {}
            Ok(Err(why)) => tally.findings.push(format!("{why} ({})", file.display())),
            Err(_) => tally.findings.push(format!("panic ({})", file.display())),
        }
    }
    let _ = std::panic::take_hook();
    tally
}

#[test]
fn mutated_scenes_never_panic() {
    if let Some(dir) = std::env::var_os("DRAPE_FUZZ_REPLAY") {
        let t = replay(Path::new(&dir));
        println!(
            "fuzz replay: {} cases, {} refused as bad input, {} stepped, {} baked, {} findings",
            t.cases,
            t.rejected,
            t.stepped,
            t.baked,
            t.findings.len()
        );
        assert!(t.findings.is_empty(), "{:#?}", t.findings);
        return;
    }
    let seconds: u64 = std::env::var("DRAPE_FUZZ_SECONDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(0);
    let (budget, cases) = if seconds > 0 {
        (Duration::from_secs(seconds), usize::MAX)
    } else {
        (Duration::from_secs(60), 400)
    };
    let seed = std::env::var("DRAPE_FUZZ_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(0xD2A9E);
    let start = Instant::now();
    let t = campaign(seed, budget, cases);
    println!(
        "fuzz: seed {seed}: {} cases in {:.0} s: {} refused as bad input, {} stepped, {} baked, \
         {} unstable, {} findings",
        t.cases,
        start.elapsed().as_secs_f64(),
        t.rejected,
        t.stepped,
        t.baked,
        t.unstable,
        t.findings.len()
    );
    let mut fields: Vec<_> = t.refused_fields.iter().collect();
    fields.sort_by_key(|(_, &n)| std::cmp::Reverse(n));
    let shown: Vec<String> = fields
        .iter()
        .take(40)
        .map(|(f, n)| format!("{f} {n}"))
        .collect();
    println!("fuzz: refusals by field: {}", shown.join(", "));
    assert!(t.findings.is_empty(), "{:#?}", t.findings);
    assert!(
        t.rejected > 0 && t.stepped > 0,
        "the mutations reach both outcomes"
    );
}
