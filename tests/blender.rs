//! The Blender add-on (`blender/drape_bake`) in Blender itself, headless: Debian's Blender 3.4,
//! which `.ci/deps` installs, runs `tests/blender_addon.py`: the add-on installed from its zip
//! bakes a skinned character's cape through drape, and Blender's evaluated baked cape equals
//! drape's OBJ frames at three frames (within 1e-6 m), as the character Blender shows equals
//! the character drape baked (the clip lined up frame for frame), and the same for a character
//! animated without an armature (written as one OBJ per frame); Cancel stops the bake with a
//! checkpoint that Resume continues from; a garment with no faces gets drape's own message.

mod common;

use serde_json::Value;

#[test]
fn the_blender_add_on_bakes_a_cape_that_plays_on_blenders_timeline() {
    let blender = std::env::var_os("PATH")
        .and_then(|paths| {
            std::env::split_paths(&paths)
                .map(|p| p.join("blender"))
                .find(|p| p.is_file())
        })
        .expect("blender is not on the PATH: run .ci/deps (it installs Debian's blender)");
    let dir = common::temp_dir();
    let work = dir.path();
    let run = std::process::Command::new(blender)
        .args(["-b", "--factory-startup", "--python"])
        .arg(std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/blender_addon.py"))
        .arg("--")
        .arg(env!("CARGO_BIN_EXE_drape"))
        .arg(work)
        // The add-on is installed into this test's folder, not the user's Blender.
        .env("BLENDER_USER_SCRIPTS", work.join("scripts"))
        .env("BLENDER_USER_CONFIG", work.join("config"))
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&run.stdout);
    let line = stdout
        .lines()
        .find_map(|l| l.strip_prefix("RESULT "))
        .unwrap_or_else(|| panic!("no result:\n{stdout}\n{}", common::stderr(&run)));
    let r: Value = serde_json::from_str(line).unwrap();
    eprintln!("{r}");
    assert_eq!(r["made"], true, "{r}");
    assert_eq!(r["cape_hidden"], true, "the garment baked from is hidden");
    assert_eq!(r["uv"], true, "the baked cape keeps its UVs");
    let mut moved = 0.0f64;
    for frame in ["1001", "1012", "1024"] {
        let f = &r["frames"][frame];
        assert_eq!(f["vertices"][0], f["vertices"][1], "frame {frame}: {f}");
        let garment = f["garment"].as_f64().unwrap();
        assert!(
            garment <= 1e-6,
            "frame {frame}: the cape Blender plays is {garment} m from drape's"
        );
        // The clip drape baked, at the frame Blender shows it: within 0.1 mm (f32 clip times).
        let character = f["character"].as_f64().unwrap();
        assert!(
            character <= 1e-4,
            "frame {frame}: the character is {character} m from drape's"
        );
        moved = moved.max(f["cape_moves"].as_f64().unwrap());
    }
    assert!(
        moved > 0.05,
        "the cape hardly moves ({moved} m): the case tests nothing"
    );
    // A character animated without an armature goes to drape as one OBJ per frame.
    for frame in ["1001", "1012", "1024"] {
        let f = &r["sequence"][frame];
        for key in ["garment", "character"] {
            let d = f[key].as_f64().unwrap();
            assert!(
                d <= 1e-6,
                "frame sequence, frame {frame}: {key} {d} m from drape's"
            );
        }
    }
    assert_eq!(r["cancelled_code"], 130, "{r}");
    let after = r["resumed"]["after_frame"]
        .as_u64()
        .expect("resumed from a checkpoint");
    assert!(
        after < 1024,
        "resumed after frame {after}: nothing was left to bake"
    );
    assert_eq!(r["resumed_frames"], 24);
    let bad = r["bad_input"].as_str().unwrap_or("");
    assert!(
        bad.contains("garments[0].mesh") && bad.contains("no triangles"),
        "drape's message does not reach the user: {bad:?}"
    );
}
