//! `drape bench peers` with the Blender `.ci/deps` installs (Debian's 3.4): both tools bake
//! the same scenes, the same code measures both, and without Blender the command says how to
//! get it.

mod common;

use std::path::Path;
use std::process::Command;

fn bench(dir: &Path, args: &[&str]) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_drape"));
    c.args(["bench", "peers", "--out"])
        .arg(dir.join("out"))
        .args(args)
        // The scenes are the repository's own.
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .env("XDG_CACHE_HOME", dir.join("cache"));
    c
}

fn mean_height(obj: &Path) -> f64 {
    let text = std::fs::read_to_string(obj).unwrap_or_else(|e| panic!("{}: {e}", obj.display()));
    let ys: Vec<f64> = text
        .lines()
        .filter_map(|l| l.strip_prefix("v "))
        .map(|l| l.split_whitespace().nth(1).unwrap().parse().unwrap())
        .collect();
    ys.iter().sum::<f64>() / ys.len() as f64
}

#[test]
fn without_blender_the_peers_bench_says_how_to_get_it_and_writes_nothing() {
    let dir = common::temp_dir();
    let d = dir.path();
    let out = bench(d, &["--quick"])
        .env("PATH", d.join("no-such-bin"))
        .env_remove("BLENDER")
        .output()
        .unwrap();
    let err = common::stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("apt install blender") && err.contains("--blender"),
        "{err}"
    );
    assert!(!d.join("out").exists());
}

#[test]
fn blender_and_drape_bake_the_same_scenes_and_are_measured_by_the_same_code() {
    let dir = common::temp_dir();
    let d = dir.path();
    let out = bench(d, &["--quick", "--frames", "12", "--keep"])
        .output()
        .unwrap();
    let err = common::stderr(&out);
    assert!(out.status.success(), "{err}");
    let csv = std::fs::read_to_string(d.join("out/bench/peers.csv")).unwrap();
    let rows: Vec<Vec<&str>> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').collect())
        .collect();
    let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    // H and the blanket on the robot, each baked by both tools, every frame measured.
    assert_eq!(rows.len(), 4, "{csv}");
    for scene in ["H (shear springs)", "blanket on RobotExpressive"] {
        let tools: Vec<&str> = rows
            .iter()
            .filter(|r| r[col("scene")] == scene)
            .map(|r| r[col("tool")])
            .collect();
        assert_eq!(tools.len(), 2, "{csv}");
        assert!(tools.contains(&"drape") && tools.iter().any(|t| t.starts_with("Blender")));
    }
    for r in &rows {
        assert_eq!(r[col("frames")], "12", "{csv}");
        let strain: f64 = r[col("mean_strain")].parse().unwrap();
        assert!(strain.is_finite() && strain >= 0.0, "{csv}");
    }
    // Blender imported the robot from the same file and placed it where drape did.
    let blanket = rows
        .iter()
        .find(|r| r[col("scene")].starts_with("blanket") && r[col("tool")] != "drape")
        .unwrap();
    let offset: f64 = blanket[col("body_offset_m")].parse().unwrap();
    assert!(offset < 1e-3, "Blender's robot is {offset} m off drape's");
    // The same fall in both: twelve frames of the sheet pinned at two corners sink the same
    // way (a conversion of gravity, mass or time that was off would show as centimetres).
    let frames = d.join("out/bench/peers-frames/scene0");
    for frame in ["cloth_0006.obj", "cloth_0012.obj"] {
        let ours = mean_height(&frames.join("drape0/obj").join(frame));
        let theirs = mean_height(&frames.join("blender-q5").join(frame));
        assert!(ours < 0.99, "{ours}: the cloth did not fall");
        assert!(
            (ours - theirs).abs() < 3e-3,
            "{frame}: drape's cloth is at {ours} m on average, Blender's at {theirs} m"
        );
    }
    // The table went into the page between its markers.
    let page = std::fs::read_to_string(d.join("out/accuracy-vs-speed.md")).unwrap();
    let begin = page.find("<!-- drape bench peers -->").unwrap();
    let end = page.find("<!-- /drape bench peers -->").unwrap();
    assert!(page[begin..end].contains("| blanket on RobotExpressive | drape |"));
    assert!(d.join("out/bench/peers-mean.svg").is_file());
    assert!(d.join("out/bench/peers-worst.svg").is_file());
}
