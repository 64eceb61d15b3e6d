//! `drape plan SCENE --wedge FIELD=V1,V2 … --out DIR`: a render-farm plan. Each combination of
//! the wedges' values becomes a scene (`DIR/scenes/<name>.json`, the original with those fields
//! set and its relative paths made relative to the plan's `scenes/` folder) and one bake
//! command (a line of `DIR/jobs.txt`, which GNU parallel, a Slurm array or `bash` runs as it is
//! from inside `DIR`: every path in the lists is relative to it, so a plan moved, or seen at
//! another path on a worker, still runs). With characters, a first step
//! (`DIR/shells.txt`, `drape shell SCENE --out DIR/shells`) builds their shells into one cache
//! folder that every bake then reuses (`--shell-cache`). `DIR/job.yaml` is the same plan as an
//! Open Job Description template (its paths through the job parameter `PlanDir`), and the
//! recipes `DIR/parallel.sh` and `DIR/slurm.sh` run it with GNU parallel or on Slurm (each task
//! a line, through `DIR/run_line.sh`). `drape plan --status DIR` reads how every variant went.
//! Every variant is validated before anything is written.

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

/// What `drape plan` was asked to plan.
struct Planned {
    scene: PathBuf,
    out: PathBuf,
    wedge: Vec<String>,
    chunk: Option<u32>,
    cpus: u32,
}

/// One wedge: the field's path and its values.
struct Wedge {
    field: String,
    values: Vec<Value>,
}

pub fn run(args: PlanArgs) -> anyhow::Result<i32> {
    if let Some(dir) = &args.status {
        return status(dir);
    }
    let (Some(scene), Some(out)) = (args.scene.clone(), args.out.clone()) else {
        unreachable!("clap requires a scene and --out without --status");
    };
    if args.cpus == 0 {
        return Err(Error::InvalidArgument {
            flag: "--cpus".into(),
            reason: "must be at least 1".into(),
        }
        .into());
    }
    let args = Planned {
        scene,
        out,
        wedge: args.wedge,
        chunk: args.chunk,
        cpus: args.cpus,
    };
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
    let plan_scenes = std::path::absolute(&args.out)
        .map_err(|e| Error::io(&args.out, "cannot resolve", e))?
        .join("scenes");
    let variants = variants(
        &original,
        &wedges,
        &stem,
        &file,
        (&base, &plan_scenes),
        args.chunk,
    )?;
    write_plan(&args.out, &stem, &variants, args.cpus)?;
    println!(
        "planned {count} bake{s} into {plan}: run them with `cd {plan} && bash jobs.txt` (in order, one at a time), `bash {plan}/parallel.sh` (GNU parallel here), `bash {plan}/slurm.sh` (Slurm) or {plan}/job.yaml (OpenJD); `drape plan --status {plan}` says how each went",
        count = variants.len(),
        s = if variants.len() == 1 { "" } else { "s" },
        plan = args.out.display(),
    );
    Ok(0)
}

/// The plan's variants: `original` (the scene `file`, named `stem`) with each combination of
/// the `wedges`' values, its paths rebased from `base` to the plan's `scenes` folder, each
/// checked as a scene and cut into chunks of `chunk` frames.
fn variants(
    original: &Value,
    wedges: &[Wedge],
    stem: &str,
    file: &str,
    (base, plan_scenes): (&Path, &Path),
    chunk: Option<u32>,
) -> Result<Vec<Variant>, Error> {
    let mut variants = Vec::new();
    for (index, combination) in combinations(wedges).into_iter().enumerate() {
        let mut scene = rebased_paths(original.clone(), base, plan_scenes);
        let mut name = stem.to_string();
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
        let parsed = Scene::parse_in(&text, &format!("{file} ({name})"), base).map_err(|e| {
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
            chunks: chunks(&parsed, chunk),
        });
    }
    Ok(variants)
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
    let values: Vec<Value> = split_values(values)
        .into_iter()
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

/// The values of a wedge, split at the commas outside brackets, braces and quotes, so a value
/// may be a JSON array or object (`position=[0,1,0],[0,2,0]`).
fn split_values(text: &str) -> Vec<&str> {
    let (mut out, mut depth, mut quoted, mut start) = (Vec::new(), 0i32, false, 0);
    let mut escaped = false;
    for (i, c) in text.char_indices() {
        match c {
            _ if escaped => escaped = false,
            '\\' if quoted => escaped = true,
            '"' => quoted = !quoted,
            '[' | '{' if !quoted => depth += 1,
            ']' | '}' if !quoted => depth -= 1,
            ',' if !quoted && depth == 0 => {
                out.push(&text[start..i]);
                start = i + 1;
            }
            _ => {}
        }
    }
    out.push(&text[start..]);
    out
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

/// The scene with its characters' files and garments' meshes, relative to `base`, made
/// relative to `scenes` instead (the variants live there): a project moved with its plan, or
/// seen by a worker at another path, still finds them. Absolute paths stay as they are.
fn rebased_paths(mut scene: Value, base: &Path, scenes: &Path) -> Value {
    let fix = |v: &mut Value| {
        if let Some(p) = v.as_str() {
            if Path::new(p).is_relative() {
                let rebased = relative(&base.join(p), scenes);
                *v = Value::String(rebased.display().to_string());
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

/// `path` relative to the folder `from`, both absolute; `.` and `..` resolved by their names
/// (a symbolic link's `..` is not followed).
fn relative(path: &Path, from: &Path) -> PathBuf {
    use std::path::Component;
    fn normal(p: &Path) -> Vec<Component<'_>> {
        let mut parts: Vec<Component> = Vec::new();
        for c in p.components() {
            match c {
                Component::CurDir => {}
                Component::ParentDir if matches!(parts.last(), Some(Component::Normal(_))) => {
                    parts.pop();
                }
                other => parts.push(other),
            }
        }
        parts
    }
    let (to, from) = (normal(path), normal(from));
    let shared = to.iter().zip(&from).take_while(|(a, b)| a == b).count();
    let mut out = PathBuf::new();
    for _ in shared..from.len() {
        out.push("..");
    }
    for c in &to[shared..] {
        out.push(c);
    }
    out
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

/// The drape a list's line runs: `$DRAPE` where a worker sets it (drape is elsewhere there),
/// else the one that planned, `exe`.
fn drape_command(exe: &str) -> String {
    let mut escaped = String::new();
    for c in exe.chars() {
        if matches!(c, '\\' | '"' | '$' | '`' | '}') {
            escaped.push('\\');
        }
        escaped.push(c);
    }
    format!("\"${{DRAPE:-{escaped}}}\"")
}

/// Writes `DIR/scenes/*.json`, `DIR/jobs.txt`, `DIR/job.yaml` and the recipes through a
/// staging folder; `cpus`: the cores each bake takes.
fn write_plan(out: &Path, stem: &str, variants: &[Variant], cpus: u32) -> Result<(), Error> {
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
        for v in variants {
            let path = scenes.join(format!("{}.json", v.name));
            std::fs::write(&path, &v.text).map_err(|e| Error::io(&path, "cannot write", e))?;
        }
        let (shells, chunk_lists) = lists(variants, &drape_command(&exe), cpus);
        let chunked = variants.iter().any(|v| !v.chunks.is_empty());
        let mut jobs = String::new();
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
        std::fs::write(&yaml_path, openjd(&exe, stem, variants, cpus))
            .map_err(|e| Error::io(&yaml_path, "cannot write", e))?;
        for (name, text) in recipes(&exe, cpus, chunk_lists.len()) {
            let path = staging.join(name);
            std::fs::write(&path, text).map_err(|e| Error::io(&path, "cannot write", e))?;
            #[cfg(unix)]
            {
                use std::os::unix::fs::PermissionsExt;
                let _ = std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o755));
            }
        }
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

/// The plan's command lists: `shells.txt`'s lines and each chunk file's (one chunk: `jobs.txt`),
/// every path relative to the plan folder; `exe_line` runs drape.
fn lists(variants: &[Variant], exe_line: &str, cpus: u32) -> (String, Vec<String>) {
    let mut shells = String::new();
    let chunked = variants.iter().any(|v| !v.chunks.is_empty());
    let chunk_count = variants
        .iter()
        .map(|v| v.chunks.len())
        .max()
        .unwrap_or(0)
        .max(1);
    // Every chunk file has a line per variant, in one order, so task i of every chunk's
    // array is variant i (Slurm's `aftercorr` pairs them): a variant with fewer chunks (a
    // wedge on `frames`) gets a line that does nothing.
    let mut chunk_lists: Vec<String> = vec![String::new(); chunk_count];
    // Every path in the lists is relative to the plan folder, which the recipes run them
    // from.
    let cache = "shells";
    for v in variants {
        let scene = quoted(&format!("scenes/{}.json", v.name));
        let bake = quoted(&format!("bakes/{}", v.name));
        let exe = exe_line;
        if v.characters {
            shells.push_str(&format!("{exe} shell {scene} --out {cache}\n"));
        }
        for (k, list) in chunk_lists.iter_mut().enumerate() {
            let until = if chunked {
                v.chunks.get(k).copied()
            } else {
                None
            };
            if chunked && until.is_none() {
                list.push_str(&format!(": {} has no chunk {}\n", v.name, k + 1));
                continue;
            }
            // Every bake resumes: one that a scheduler runs again after a pre-emption
            // continues from its last checkpoint, and each chunk from the one before.
            let mut line = format!("{exe} bake {scene} --out {bake} --resume --threads {cpus}");
            if v.characters {
                line.push_str(&format!(" --shell-cache {cache}"));
            }
            if let Some(u) = until {
                line.push_str(&format!(" --until {u}"));
            }
            line.push('\n');
            list.push_str(&line);
        }
    }
    (shells, chunk_lists)
}

/// The plan as an Open Job Description job template (specification 2023-09): one step whose
/// tasks range over the variants; with chunks, a chain of steps per variant ([`chunk_step`]),
/// each chunk after the variant's chunk before, its one task the variant and the frame its
/// chunk stops after.
fn openjd(exe: &str, stem: &str, variants: &[Variant], cpus: u32) -> String {
    let json = |s: &str| serde_json::to_string(s).expect("a string serialises");
    // Paths through the job parameters: `PlanDir` (PATH, by default the template's own folder,
    // which a scheduler's path mapping remaps for a worker that sees the plan elsewhere) and
    // `Drape` (the executable on the workers; a STRING, since OpenJD wants a PATH's default
    // relative to the template).
    let scene = json("{{Param.PlanDir}}/scenes/{{Task.Param.Variant}}.json");
    let bake = json("{{Param.PlanDir}}/bakes/{{Task.Param.Variant}}");
    let cache = json("{{Param.PlanDir}}/shells");
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
            json("{{Param.Drape}}")
        ));
        s
    };
    let mut text = format!(
        "specificationVersion: 'jobtemplate-2023-09'\nname: {}\nparameterDefinitions:\n\
         - name: PlanDir\n  type: PATH\n  objectType: DIRECTORY\n  dataFlow: INOUT\n  default: \".\"\n\
         - name: Drape\n  type: STRING\n  default: {}\nsteps:\n",
        json(&format!("drape plan of {stem}")),
        json(exe)
    );
    let all: Vec<(&Variant, Option<u32>)> = variants.iter().map(|v| (v, None)).collect();
    let mut bake_args =
        format!("'bake', {scene}, '--out', {bake}, '--resume', '--threads', '{cpus}'");
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
    // One chain of steps per variant: a step's dependencies are all-or-nothing (every task of
    // the step before must succeed), so one step per chunk over every variant would let a
    // variant that fails hold back every other variant's next chunk.
    for (i, v) in variants.iter().enumerate() {
        let mut previous = after.clone();
        for (k, &until) in v.chunks.iter().enumerate() {
            let name = json(&chunk_step(k, &v.name, i));
            text.push_str(&step(
                &name,
                &[(v, Some(until))],
                &bake_args,
                previous.as_deref(),
            ));
            previous = Some(name);
        }
    }
    text
}

/// The OpenJD step of chunk `k` (from 0) of variant `name`, the `index`-th: `bake_02 NAME`, or
/// `bake_02 variant 3` for a name that would make it longer than a step name may be (64).
fn chunk_step(k: usize, name: &str, index: usize) -> String {
    let step = format!("bake_{:02} {name}", k + 1);
    if step.chars().count() <= 64 {
        step
    } else {
        format!("bake_{:02} variant {}", k + 1, index + 1)
    }
}

/// The plan's recipes, written beside its lists: `run_line.sh FILE N` runs line N of a list
/// with bash and fails when the file or the line is missing; `slurm.sh` submits the plan to
/// Slurm (one array per list, each sized from its own file; chunks chained with `aftercorr`,
/// so one variant's failure stops only its own later chunks); `parallel.sh` runs it here with
/// GNU parallel, every variant to its end whatever another does. Both end by reporting each
/// variant's state (`drape plan --status`).
fn recipes(exe: &str, cpus: u32, chunks: usize) -> Vec<(&'static str, String)> {
    let drape = drape_command(exe);
    let run_line = r#"#!/bin/bash
# Runs line N of FILE (a list of this plan: shells.txt, jobs.txt, chunks/chunk_NN.txt) with
# bash, so a scheduler's task is one line; fails when the file or the line is missing. The
# line runs in the plan folder (this script's own), which its paths are relative to; a worker
# whose drape is elsewhere sets DRAPE to it.
set -euo pipefail
file=$1 n=$2
[ -f "$file" ] || { echo "drape plan: no file $file" >&2; exit 2; }
line=$(sed -n "${n}p" "$file")
[ -n "$line" ] || { echo "drape plan: $file has no line $n" >&2; exit 2; }
cd "$(dirname "$0")"
exec bash -c "$line"
"#
    .to_string();
    let lists = if chunks > 1 {
        (1..=chunks)
            .map(|k| format!("chunks/chunk_{k:02}.txt"))
            .collect::<Vec<_>>()
            .join(" ")
    } else {
        "jobs.txt".to_string()
    };
    let slurm = format!(
        r#"#!/bin/bash
# Submits this plan to Slurm (run it once, where `sbatch` works; the plan folder must be on
# storage every node sees). Each bake takes {cpus} CPUs (`drape plan --cpus`). One array per
# list, sized from that list: the shells first (a bake builds any shell a failed task left
# out), then the bakes, or each chunk after the same variant's previous one (`aftercorr`:
# task i after task i, so a variant that fails holds back only its own later chunks, which
# stay pending with reason DependencyNeverSatisfied). A requeued task's log keeps every run
# (`--open-mode=append`). Extra arguments go to every `sbatch` (a partition, an account).
# Prints the job ids; when they are done, `drape plan --status PLAN` says how each variant
# went.
set -euo pipefail
plan=$(cd "$(dirname "$0")" && pwd)
mkdir -p "$plan/logs"
submit() {{ # LIST DEPENDENCY
  local n
  n=$(wc -l < "$plan/$1")
  sbatch --parsable "${{@:3}}" $2 --cpus-per-task={cpus} --array=1-"$n" --open-mode=append     --job-name="drape-$(basename "$1" .txt)" --output="$plan/logs/%x_%a.out"     --wrap "bash '$plan/run_line.sh' '$plan/$1' \$SLURM_ARRAY_TASK_ID"
}}
after=""
if [ -f "$plan/shells.txt" ]; then
  shells=$(submit shells.txt "" "$@")
  echo "shells: job $shells"
  after="--dependency=afterany:$shells"
fi
previous=""
for list in {lists}; do
  if [ -n "$previous" ]; then after="--dependency=aftercorr:$previous"; fi
  previous=$(submit "$list" "$after" "$@")
  echo "$list: job $previous"
done
echo "when they are done: drape plan --status $plan"
"#
    );
    let parallel = format!(
        r#"#!/bin/bash
# Runs this plan on this machine with GNU parallel, as many bakes at a time as {cpus}-CPU
# bakes fit on its cores (`drape plan --cpus`): the shells first, then the bakes, or chunk
# after chunk. A bake that fails does not stop the others (a failed variant's later chunks
# fail again at once); the exit code is that of `drape plan --status`: 0 when every variant
# is done. The lists' paths are relative to the plan folder, where they run.
set -uo pipefail
plan=$(cd "$(dirname "$0")" && pwd)
cd "$plan"
at_once=$(( $(nproc) / {cpus} ))
[ "$at_once" -ge 1 ] || at_once=1
if [ -f "$plan/shells.txt" ]; then
  parallel -j "$at_once" < shells.txt || echo "drape plan: a shell failed; its bakes build it" >&2
fi
for list in {lists}; do
  parallel -j "$at_once" < "$list" || echo "drape plan: a bake of $list failed" >&2
done
exec {drape} plan --status .
"#
    );
    vec![
        ("run_line.sh", run_line),
        ("slurm.sh", slurm),
        ("parallel.sh", parallel),
    ]
}

/// `drape plan --status DIR`: each variant of the plan in `dir` (its `scenes/`) with the state
/// its `bakes/<name>/report.json` says; 0 when every one is done, else 1.
fn status(dir: &Path) -> anyhow::Result<i32> {
    let scenes = dir.join("scenes");
    let mut names: Vec<String> = std::fs::read_dir(&scenes)
        .map_err(|e| Error::InvalidArgument {
            flag: "--status".into(),
            reason: format!("{} is not a plan folder ({e})", dir.display()),
        })?
        .filter_map(|e| e.ok())
        .filter_map(|e| {
            let p = e.path();
            let stem = p.file_stem()?.to_string_lossy().into_owned();
            (p.extension()? == "json").then_some(stem)
        })
        .collect();
    names.sort();
    let mut done = 0;
    for name in &names {
        let report = dir.join("bakes").join(name).join("report.json");
        let state = match std::fs::read_to_string(&report)
            .ok()
            .and_then(|t| serde_json::from_str::<Value>(&t).ok())
        {
            None => "not baked yet".to_string(),
            Some(r) => {
                let (baked, asked) = (&r["frames_baked"], &r["frames_requested"]);
                let frames = format!("{baked} of {asked} frames");
                if let Some(f) = r["failure"].as_object() {
                    format!(
                        "failed at frame {}: {} ({frames})",
                        f["frame"],
                        f["reason"].as_str().unwrap_or("")
                    )
                } else if r["interrupted"].is_object() {
                    format!(
                        "interrupted after frame {} ({frames}); resumable",
                        r["interrupted"]["after_frame"]
                    )
                } else if r["until"].is_u64() && baked != asked {
                    format!("in chunks: stopped after frame {} ({frames})", r["until"])
                } else if baked == asked && r["stable"] == true {
                    done += 1;
                    format!(
                        "done: {frames}, stable, frames_hash {}",
                        r["frames_hash"].as_str().unwrap_or("")
                    )
                } else {
                    format!("incomplete ({frames})")
                }
            }
        };
        println!("{name}: {state}");
    }
    println!("{done} of {} variants done", names.len());
    Ok(if done == names.len() && !names.is_empty() {
        0
    } else {
        1
    })
}

#[cfg(test)]
mod tests {
    use super::{chunk_step, relative};
    use std::path::Path;

    #[test]
    fn a_path_relative_to_a_folder_climbs_out_of_it_by_name() {
        let r = |a: &str, b: &str| relative(Path::new(a), Path::new(b)).display().to_string();
        assert_eq!(
            r("/p/shot/a.obj", "/p/farm/plan/scenes"),
            "../../../shot/a.obj"
        );
        assert_eq!(r("/p/shot/./x/../a.obj", "/p/shot"), "a.obj");
        assert_eq!(r("/p/plan/scenes/m.obj", "/p/plan/scenes"), "m.obj");
        assert_eq!(r("/a.obj", "/p/q"), "../../a.obj");
    }

    #[test]
    fn a_chunk_step_is_named_by_its_variant_while_the_name_fits() {
        assert_eq!(
            chunk_step(1, "h_solver.omega-1.3", 1),
            "bake_02 h_solver.omega-1.3"
        );
        // OpenJD refuses step names over 64 characters (`openjd check`: "name must be at most
        // 64 characters long").
        let fits = "x".repeat(56);
        assert_eq!(chunk_step(0, &fits, 0).chars().count(), 64);
        assert_eq!(chunk_step(0, &format!("{fits}y"), 2), "bake_01 variant 3");
    }
}
