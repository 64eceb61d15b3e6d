//! `drape plan SCENE --wedge FIELD=V1,V2 … --out DIR`: a render-farm plan. Each combination of
//! the wedges' values becomes a scene (`DIR/scenes/<name>.json`, the original with those fields
//! set and its relative paths made absolute) and one bake command (a line of `DIR/jobs.txt`,
//! which GNU parallel, a Slurm array or `bash` runs as it is). With characters, a first step
//! (`DIR/shells.txt`, `drape shell SCENE --out DIR/shells`) builds their shells into one cache
//! folder that every bake then reuses (`--shell-cache`). `DIR/job.yaml` is the same plan as an
//! Open Job Description template. Every variant is validated before anything is written.

use super::args::PlanArgs;
use drape::scene::Scene;
use drape::Error;
use serde_json::Value;
use std::path::{Path, PathBuf};

/// One planned bake: its name, its scene's text, and whether it has characters (then its
/// shells are built in a first step).
struct Variant {
    name: String,
    text: String,
    characters: bool,
    /// The shot frame each chunk stops after (`--until`; the last: the shot's last frame), in
    /// order; empty without chunks.
    chunks: Vec<u32>,
}

/// One wedge: the field's path and its values.
struct Wedge {
    field: String,
    values: Vec<Value>,
}

pub fn run(args: PlanArgs) -> anyhow::Result<i32> {
    if args.chunk == Some(0) {
        return Err(Error::InvalidArgument {
            flag: "--chunk".into(),
            reason: "must be at least 1 frame".into(),
        }
        .into());
    }
    let file = args.scene.display().to_string();
    // The original must be a valid scene on its own.
    Scene::load(&args.scene)?;
    let text = std::fs::read_to_string(&args.scene)
        .map_err(|e| Error::io(&args.scene, "cannot read", e))?;
    let original: Value =
        serde_json::from_str(text.trim_start_matches('\u{feff}')).map_err(|e| {
            Error::InvalidField {
                file: file.clone(),
                field: "(top level)".into(),
                reason: e.to_string(),
            }
        })?;
    let base = args
        .scene
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let base = std::path::absolute(base).map_err(|e| Error::io(base, "cannot resolve", e))?;
    let wedges = args
        .wedge
        .iter()
        .map(|w| parse_wedge(w))
        .collect::<Result<Vec<_>, _>>()?;
    let stem = original["name"]
        .as_str()
        .map(str::to_string)
        .or_else(|| {
            args.scene
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
        })
        .unwrap_or_else(|| "scene".into());
    let mut variants = Vec::new();
    for (index, combination) in combinations(&wedges).into_iter().enumerate() {
        let mut scene = absolute_paths(original.clone(), &base);
        let mut name = stem.clone();
        for (wedge, value) in wedges.iter().zip(&combination) {
            set(&mut scene, &wedge.field, value.clone()).map_err(|reason| {
                Error::InvalidArgument {
                    flag: "--wedge".into(),
                    reason: format!("{}: {reason}", wedge.field),
                }
            })?;
            name.push_str(&format!(
                "_{}-{}",
                label(&wedge.field),
                label(&value_text(value))
            ));
        }
        // A name too long for a file name (many or long wedges) becomes the variant's number;
        // its scene file still holds every value.
        if name.len() > drape::scene::MAX_NAME_BYTES {
            name = format!("{}_{:04}", stem, index + 1);
        }
        scene["name"] = Value::String(name.clone());
        let text = serde_json::to_string_pretty(&scene).expect("JSON serialises");
        let parsed = Scene::parse_in(&text, &format!("{file} ({name})"), &base).map_err(|e| {
            Error::InvalidArgument {
                flag: "--wedge".into(),
                reason: format!("variant {name}: {e}"),
            }
        })?;
        let characters = scene["characters"]
            .as_array()
            .is_some_and(|c| !c.is_empty());
        variants.push(Variant {
            name,
            text,
            characters,
            chunks: chunks(&parsed, args.chunk),
        });
    }
    write_plan(&args.out, &stem, &variants)?;
    println!(
        "planned {} bake{} into {}: run them with `bash {}` (or GNU parallel, a Slurm array, OpenJD: docs/farm.md)",
        variants.len(),
        if variants.len() == 1 { "" } else { "s" },
        args.out.display(),
        args.out.join("jobs.txt").display()
    );
    Ok(0)
}

/// The shot frames the chunks of `chunk` frames of `scene` stop after (the last one its last
/// frame); none without chunks. A pre-roll is chunked with the frames: the first chunk
/// starts with it, before `frame_start`.
fn chunks(scene: &Scene, chunk: Option<u32>) -> Vec<u32> {
    let Some(n) = chunk else {
        return Vec::new();
    };
    let scene = &scene.with_preroll();
    let mut ends: Vec<u32> = (1..)
        .map(|k: u32| k.saturating_mul(n))
        .take_while(|&e| e < scene.frames)
        .map(|e| scene.frame_start + e - 1)
        .collect();
    ends.push(scene.frame_start + scene.frames - 1);
    ends
}

/// `FIELD=V1,V2,…`; each value JSON (a number, `true`, `"text"`) or else plain text.
fn parse_wedge(text: &str) -> Result<Wedge, Error> {
    let bad = |reason: &str| Error::InvalidArgument {
        flag: "--wedge".into(),
        reason: format!("{text:?}: {reason}"),
    };
    let (field, values) = text
        .split_once('=')
        .ok_or_else(|| bad("expected FIELD=V1,V2,… (e.g. solver.iterations=5,10)"))?;
    if field.is_empty() || field.chars().any(char::is_whitespace) {
        return Err(bad("the field is empty or has spaces"));
    }
    let values: Vec<Value> = values
        .split(',')
        .filter(|v| !v.is_empty())
        .map(|v| serde_json::from_str(v).unwrap_or_else(|_| Value::String(v.to_string())))
        .collect();
    if values.is_empty() {
        return Err(bad("no values"));
    }
    Ok(Wedge {
        field: field.to_string(),
        values,
    })
}

/// Every combination of the wedges' values, the first wedge slowest.
fn combinations(wedges: &[Wedge]) -> Vec<Vec<Value>> {
    wedges.iter().fold(vec![Vec::new()], |acc, w| {
        acc.iter()
            .flat_map(|prefix| {
                w.values.iter().map(move |v| {
                    let mut c = prefix.clone();
                    c.push(v.clone());
                    c
                })
            })
            .collect()
    })
}

/// Sets `field` (`a.b`, `a[2].b`) of `scene` to `value`; objects on the way are created, arrays
/// must have the element.
fn set(scene: &mut Value, field: &str, value: Value) -> Result<(), String> {
    let mut at = scene;
    let parts: Vec<&str> = field.split('.').collect();
    for (i, part) in parts.iter().enumerate() {
        let (key, indices) = match part.find('[') {
            Some(k) => (&part[..k], &part[k..]),
            None => (*part, ""),
        };
        if key.is_empty() {
            return Err(format!("{part:?} names no field"));
        }
        let object = at
            .as_object_mut()
            .ok_or_else(|| format!("{key} is not inside an object"))?;
        let mut slot = object.entry(key.to_string()).or_insert(Value::Null);
        for index in indices.split('[').filter(|s| !s.is_empty()) {
            let n: usize = index
                .strip_suffix(']')
                .and_then(|n| n.parse().ok())
                .ok_or_else(|| format!("{part:?}: expected an index like [0]"))?;
            let len = slot.as_array().map_or(0, Vec::len);
            slot = slot
                .as_array_mut()
                .and_then(|a| a.get_mut(n))
                .ok_or_else(|| format!("{key} has {len} elements, no [{n}]"))?;
        }
        if i + 1 == parts.len() {
            *slot = value;
            return Ok(());
        }
        if slot.is_null() {
            *slot = Value::Object(Default::default());
        }
        at = slot;
    }
    Ok(())
}

/// The scene with its characters' files and garments' meshes made absolute (the variants live
/// in another folder).
fn absolute_paths(mut scene: Value, base: &Path) -> Value {
    let fix = |v: &mut Value| {
        if let Some(p) = v.as_str() {
            if Path::new(p).is_relative() {
                *v = Value::String(base.join(p).display().to_string());
            }
        }
    };
    for (list, key) in [("characters", "file"), ("garments", "mesh")] {
        if let Some(items) = scene.get_mut(list).and_then(Value::as_array_mut) {
            for item in items {
                if let Some(v) = item.get_mut(key) {
                    fix(v);
                }
            }
        }
    }
    scene
}

fn value_text(v: &Value) -> String {
    match v {
        Value::String(s) => s.clone(),
        other => other.to_string(),
    }
}

/// A piece of a file name: letters, digits, `.` and `-`; anything else becomes `_`.
fn label(text: &str) -> String {
    text.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '.' || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// `text` quoted for a POSIX shell.
fn quoted(text: &str) -> String {
    format!("'{}'", text.replace('\'', r"'\''"))
}

/// Writes `DIR/scenes/*.json`, `DIR/jobs.txt` and `DIR/job.yaml` through a staging folder.
fn write_plan(out: &Path, stem: &str, variants: &[Variant]) -> Result<(), Error> {
    if out.exists()
        && std::fs::read_dir(out)
            .map(|mut d| d.next().is_some())
            .unwrap_or(true)
    {
        return Err(Error::InvalidArgument {
            flag: "--out".into(),
            reason: format!("{} exists and is not empty", out.display()),
        });
    }
    let out = std::path::absolute(out).map_err(|e| Error::io(out, "cannot resolve", e))?;
    let name = out
        .file_name()
        .map_or("plan".into(), |n| n.to_string_lossy().into_owned());
    let staging = out.with_file_name(format!(".{name}.plan-{}", std::process::id()));
    let result = (|| {
        let scenes = staging.join("scenes");
        std::fs::create_dir_all(&scenes).map_err(|e| Error::io(&scenes, "cannot create", e))?;
        let exe = std::env::current_exe().unwrap_or_else(|_| PathBuf::from("drape"));
        let exe = exe.display().to_string();
        let (mut jobs, mut shells) = (String::new(), String::new());
        let chunked = variants.iter().any(|v| !v.chunks.is_empty());
        let mut chunk_lists: Vec<String> = Vec::new();
        let cache = quoted(&out.join("shells").display().to_string());
        for v in variants {
            let path = scenes.join(format!("{}.json", v.name));
            std::fs::write(&path, &v.text).map_err(|e| Error::io(&path, "cannot write", e))?;
            let scene = quoted(
                &out.join("scenes")
                    .join(format!("{}.json", v.name))
                    .display()
                    .to_string(),
            );
            let bake = quoted(&out.join("bakes").join(&v.name).display().to_string());
            let exe = quoted(&exe);
            if v.characters {
                shells.push_str(&format!("{exe} shell {scene} --out {cache}\n"));
            }
            let ends: Vec<Option<u32>> = if chunked {
                v.chunks.iter().copied().map(Some).collect()
            } else {
                vec![None]
            };
            for (k, until) in ends.into_iter().enumerate() {
                // Every bake resumes: one that a scheduler runs again after a pre-emption
                // continues from its last checkpoint, and each chunk from the one before.
                let mut line = format!("{exe} bake {scene} --out {bake} --resume");
                if v.characters {
                    line.push_str(&format!(" --shell-cache {cache}"));
                }
                if let Some(u) = until {
                    line.push_str(&format!(" --until {u}"));
                }
                line.push('\n');
                if chunk_lists.len() <= k {
                    chunk_lists.resize(k + 1, String::new());
                }
                chunk_lists[k].push_str(&line);
            }
        }
        // Chunk after chunk: `bash jobs.txt` runs every bake to the end in order.
        for list in &chunk_lists {
            jobs.push_str(list);
        }
        if chunked {
            let folder = staging.join("chunks");
            std::fs::create_dir_all(&folder).map_err(|e| Error::io(&folder, "cannot create", e))?;
            for (k, list) in chunk_lists.iter().enumerate() {
                let path = folder.join(format!("chunk_{:02}.txt", k + 1));
                std::fs::write(&path, list).map_err(|e| Error::io(&path, "cannot write", e))?;
            }
        }
        let jobs_path = staging.join("jobs.txt");
        std::fs::write(&jobs_path, jobs).map_err(|e| Error::io(&jobs_path, "cannot write", e))?;
        if !shells.is_empty() {
            let path = staging.join("shells.txt");
            std::fs::write(&path, shells).map_err(|e| Error::io(&path, "cannot write", e))?;
        }
        let yaml_path = staging.join("job.yaml");
        std::fs::write(&yaml_path, openjd(&exe, &out, stem, variants))
            .map_err(|e| Error::io(&yaml_path, "cannot write", e))?;
        if out.exists() {
            std::fs::remove_dir(&out).map_err(|e| Error::io(&out, "cannot replace", e))?;
        }
        std::fs::rename(&staging, &out).map_err(|e| Error::io(&out, "cannot create", e))
    })();
    if result.is_err() {
        let _ = std::fs::remove_dir_all(&staging);
    }
    result
}

/// The plan as an Open Job Description job template (specification 2023-09): one step whose
/// tasks range over the variants; with chunks, one step per chunk, each after the one before,
/// its tasks pairing each variant with the frame its chunk stops after.
fn openjd(exe: &str, out: &Path, stem: &str, variants: &[Variant]) -> String {
    let json = |s: &str| serde_json::to_string(s).expect("a string serialises");
    let scene = json(&format!(
        "{}/{{{{Task.Param.Variant}}}}.json",
        out.join("scenes").display()
    ));
    let bake = json(&format!(
        "{}/{{{{Task.Param.Variant}}}}",
        out.join("bakes").display()
    ));
    let cache = json(&out.join("shells").display().to_string());
    let characters = variants.iter().any(|v| v.characters);
    // A step over `tasks` (variant, and the frame its chunk stops after) running `args`, after
    // `after` when given.
    let step = |name: &str, tasks: &[(&Variant, Option<u32>)], args: &str, after: Option<&str>| {
        let names: Vec<String> = tasks.iter().map(|(v, _)| json(&v.name)).collect();
        let mut s = format!(
            "- name: {name}\n  parameterSpace:\n    taskParameterDefinitions:\n    - name: Variant\n      type: STRING\n      range: [{}]\n",
            names.join(", ")
        );
        if tasks.iter().any(|(_, u)| u.is_some()) {
            let ends: Vec<String> = tasks
                .iter()
                .map(|(_, u)| u.unwrap_or_default().to_string())
                .collect();
            s.push_str(&format!(
                "    - name: Until\n      type: INT\n      range: [{}]\n    combination: \"(Variant, Until)\"\n",
                ends.join(", ")
            ));
        }
        if let Some(a) = after {
            s.push_str(&format!("  dependencies:\n  - dependsOn: {a}\n"));
        }
        s.push_str(&format!(
            "  script:\n    actions:\n      onRun:\n        command: {}\n        args: [{args}]\n",
            json(exe)
        ));
        s
    };
    let mut text = format!(
        "specificationVersion: 'jobtemplate-2023-09'\nname: {}\nsteps:\n",
        json(&format!("drape plan of {stem}"))
    );
    let all: Vec<(&Variant, Option<u32>)> = variants.iter().map(|v| (v, None)).collect();
    let mut bake_args = format!("'bake', {scene}, '--out', {bake}, '--resume'");
    let mut after = None;
    if characters {
        text.push_str(&step(
            "shells",
            &all,
            &format!("'shell', {scene}, '--out', {cache}"),
            None,
        ));
        bake_args.push_str(&format!(", '--shell-cache', {cache}"));
        after = Some("shells".to_string());
    }
    let chunks = variants.iter().map(|v| v.chunks.len()).max().unwrap_or(0);
    if chunks == 0 {
        text.push_str(&step("bake", &all, &bake_args, after.as_deref()));
        return text;
    }
    bake_args.push_str(", '--until', '{{Task.Param.Until}}'");
    for k in 0..chunks {
        let tasks: Vec<(&Variant, Option<u32>)> = variants
            .iter()
            .filter_map(|v| v.chunks.get(k).map(|&u| (v, Some(u))))
            .collect();
        let name = format!("bake_{:02}", k + 1);
        text.push_str(&step(&name, &tasks, &bake_args, after.as_deref()));
        after = Some(name);
    }
    text
}
