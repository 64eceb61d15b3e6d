//! `drape bench docs --quick`: both studies in reduced form, so they cannot rot. The files they
//! write are read back and their findings asserted on iteration counts and errors, never on time.
//! `drape bench characters --quick` likewise: its rows are checked against their own counts and
//! the bakes' frames against each other, never its times.

mod common;

use std::collections::BTreeMap;
use std::path::Path;

/// Rows of a CSV file as maps from column name to text.
fn csv(path: &Path) -> Vec<BTreeMap<String, String>> {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().expect("header").split(',').collect();
    lines
        .map(|l| {
            header
                .iter()
                .zip(l.split(','))
                .map(|(h, v)| (h.to_string(), v.to_string()))
                .collect()
        })
        .collect()
}

/// Error curve of (scene, backend prefix, method) from a convergence CSV.
fn curve(rows: &[BTreeMap<String, String>], backend: &str, method: &str) -> Vec<f64> {
    rows.iter()
        .filter(|r| r["backend"].starts_with(backend) && r["method"] == method)
        .map(|r| r["error_m2"].parse().expect("error"))
        .collect()
}

#[test]
fn quick_studies_write_charts_tables_and_show_the_findings() {
    let dir = common::temp_dir();
    let out = common::drape(dir.path(), &["bench", "docs", "--quick", "--out", "docs"]);
    assert!(out.status.success(), "{}", common::stderr(&out));
    let docs = dir.path().join("docs");
    let page = std::fs::read_to_string(docs.join("accuracy-vs-speed.md")).expect("page");
    let bench = docs.join("bench");
    // Every chart the page shows exists and is a complete SVG.
    for line in page.lines().filter(|l| l.starts_with("![")) {
        let file = line
            .split("](")
            .nth(1)
            .and_then(|r| r.strip_suffix(')'))
            .expect("link");
        let svg =
            std::fs::read_to_string(docs.join(file)).unwrap_or_else(|e| panic!("{file}: {e}"));
        assert!(
            svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"),
            "{file}"
        );
    }
    assert!(
        page.matches("![").count() >= 10,
        "charts on the page:\n{page}"
    );

    // Convergence on scene E, CPU: red-black ≡ sequential GS per iteration, Jacobi behind,
    // SOR ω = 1.7 ahead; every curve starts at the same error and falls.
    let e = csv(&bench.join("convergence-E.csv"));
    let gs = curve(&e, "cpu", "gs");
    let rbgs = curve(&e, "cpu", "rbgs");
    let jacobi = curve(&e, "cpu", "jacobi");
    let sor = curve(&e, "cpu", "rbgs ω=1.7");
    assert_eq!(gs.len(), 21);
    for k in 1..gs.len() {
        assert!(
            (rbgs[k] - gs[k]).abs() <= 5e-3 * gs[k],
            "iteration {k}: {} vs {}",
            rbgs[k],
            gs[k]
        );
        assert!(gs[k] < gs[k - 1] && rbgs[k] < rbgs[k - 1]);
    }
    assert!(
        jacobi[20] > gs[20] && sor[20] < gs[20],
        "jacobi {} gs {} sor {}",
        jacobi[20],
        gs[20],
        sor[20]
    );
    // Same curves on a GPU, when one is present (lavapipe here and in CI).
    let gpu = curve(&e, "gpu", "rbgs");
    if !gpu.is_empty() {
        for (g, c) in gpu.iter().zip(&rbgs) {
            assert!((g - c).abs() <= 1e-4 * c, "gpu {g} vs cpu {c}");
        }
    }
    // Scene H: the step's error falls from the inertial prediction.
    let h = csv(&bench.join("convergence-H.csv"));
    let rbgs_h = curve(&h, "cpu", "rbgs");
    assert!(
        rbgs_h[20] < 0.1 * rbgs_h[0],
        "H rbgs {} → {}",
        rbgs_h[0],
        rbgs_h[20]
    );
    // Budgets: more time never buys fewer iterations.
    let budgets = csv(&bench.join("convergence-budgets.csv"));
    for m in ["gs", "rbgs", "jacobi"] {
        let its: Vec<u32> = budgets
            .iter()
            .filter(|r| r["scene"] == "E" && r["backend"] == "cpu" && r["method"] == m)
            .map(|r| r["iterations"].parse().expect("iterations"))
            .collect();
        assert_eq!(its.len(), 4);
        assert!(its.windows(2).all(|w| w[0] <= w[1]), "{m}: {its:?}");
    }

    // Integrators: explicit Euler never stable; Verlet's measured limit at or below 2/ω_max and
    // within the ladder's spacing of it; implicit Euler stable at a whole frame.
    let stability = csv(&bench.join("integrators-stability.csv"));
    assert!(!stability.is_empty());
    for r in &stability {
        let omega: f64 = r["omega_max"].parse().expect("omega");
        let limit = r["largest_stable_step_s"].parse::<f64>().ok();
        match r["method"].as_str() {
            "explicit_euler" => assert_eq!(limit, None, "{r:?}"),
            "verlet" => {
                let h = limit.expect("Verlet has a stable step");
                assert!(h <= 2.0 / omega && h >= 0.6 * 2.0 / omega, "{r:?}");
            }
            "implicit_euler" => assert!(limit.expect("stable") >= 1.0 / 60.0 - 1e-12, "{r:?}"),
            _ => {}
        }
    }
    // Accuracy: RK4 gets more accurate with smaller steps, and beats Verlet at equal steps.
    let acc = csv(&bench.join("integrators-accuracy-F.csv"));
    let error = |m: &str, s: &str| -> f64 {
        acc.iter()
            .find(|r| r["method"] == m && r["substeps"] == s)
            .and_then(|r| r["rms_error_m"].parse().ok())
            .unwrap_or(f64::NAN)
    };
    assert!(
        error("rk4", "200") < error("rk4", "100"),
        "RK4 error must fall"
    );
    assert!(
        error("rk4", "100") < error("verlet", "100"),
        "RK4 vs Verlet"
    );
    // The rule 0.4π√(m/k): holds for RK4 on a chain, fails for Verlet on scene W; Verlet on the
    // chain within 5 % of its theory 2/ω_max.
    let rule = csv(&bench.join("integrators-rule.csv"));
    let value = |case: &str, column: &str| -> f64 {
        rule.iter()
            .find(|r| r["case"].starts_with(case))
            .and_then(|r| r[column].parse().ok())
            .unwrap_or_else(|| panic!("{case} {column} in {rule:?}"))
    };
    let bound = 0.4 * std::f64::consts::PI;
    assert!(value("rope", "rk4_limit_over_sqrt_m_over_k") >= bound);
    assert!(value("scene W", "verlet_limit_over_sqrt_m_over_k") < bound);
    let chain_theory = 2.0 / value("rope", "omega_max_sqrt_m_over_k");
    let chain_verlet = value("rope", "verlet_limit_over_sqrt_m_over_k");
    assert!(
        (chain_verlet / chain_theory - 1.0).abs() < 0.05,
        "{chain_verlet} vs {chain_theory}"
    );
    // The cost table names every method at every size.
    let cost = csv(&bench.join("integrators-cost.csv"));
    assert_eq!(cost.len(), 2 * 6);
}

/// `drape bench characters --quick`: H with shear springs, H with bend springs too (the
/// garments' model) and a cape, two rounds on one and two threads. Every bake is in the CSV; its figures per particle- and spring-iteration are its
/// time over its own counts (H: 100 substeps × 1 iteration; the cape: 20 × 10); each scene bakes
/// the same frames on either thread count in either round; H's ratios to itself are 1.
#[test]
fn the_characters_bench_times_every_bake_against_its_own_counts() {
    let dir = common::temp_dir();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_drape"))
        .args([
            "bench",
            "characters",
            "--quick",
            "--rounds",
            "2",
            "--threads",
            "1,2",
        ])
        .args(["--frames", "3", "--out"])
        .arg(dir.path().join("docs"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .env("XDG_CACHE_HOME", dir.path().join("cache"))
        .output()
        .expect("drape runs");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}", common::stderr(&out));
    let rows = csv(&dir.path().join("docs/bench/characters.csv"));
    assert_eq!(rows.len(), 3 * 2 * 2, "scenes × thread counts × rounds");
    let number = |r: &BTreeMap<String, String>, k: &str| -> f64 { r[k].parse().expect(k) };
    for r in &rows {
        let work = number(r, "particle_iterations_per_frame");
        let expected = if r["scene"] == "cape_walk" {
            200.0
        } else {
            100.0
        };
        assert_eq!(work, expected, "{r:?}");
        let ms = number(r, "ms_per_frame");
        for (column, count) in [
            ("ns_per_particle_iteration", "particles"),
            ("ns_per_spring_iteration", "springs"),
        ] {
            let per = ms * 1e6 / (number(r, count) * work);
            assert!(
                (number(r, column) - per).abs() <= 1e-3 * per + 1e-3,
                "{column}: {r:?}"
            );
        }
        // How busy the machine was: a share of the team's waits on two threads, none on one.
        let asleep = &r["team_waits_asleep"];
        match r["threads"].as_str() {
            "1" => assert!(asleep.is_empty(), "{r:?}"),
            _ => assert!(
                asleep.is_empty() || (0.0..=1.0).contains(&number(r, "team_waits_asleep")),
                "{r:?}"
            ),
        }
        let same: Vec<_> = rows.iter().filter(|o| o["scene"] == r["scene"]).collect();
        assert!(
            same.iter().all(|o| o["frames_hash"] == r["frames_hash"]),
            "{same:?}"
        );
    }
    // The table's rows of one reference, one per thread count.
    let rows_of = |label: &str| -> Vec<&str> {
        let start = format!("| {label} |");
        let found: Vec<&str> = stdout.lines().filter(|l| l.starts_with(&start)).collect();
        assert_eq!(found.len(), 2, "{label}: {stdout}");
        found
    };
    let h_rows = rows_of("H with shear springs");
    assert!(
        h_rows.iter().all(|l| l.matches("(1.00)").count() == 2),
        "{stdout}"
    );
    // H on the garments' model: bend springs added, so more springs per particle than H's,
    // and its ratio to itself is 1.
    let springs_per = |scene: &str| {
        let r = rows.iter().find(|r| r["scene"] == scene).expect(scene);
        number(r, "springs") / number(r, "particles")
    };
    assert!(
        springs_per("H with shear and bend springs") > springs_per("H with shear springs") + 1.5
    );
    assert!(
        rows_of("H with shear and bend springs").iter().all(|l| l
            .split(" | ")
            .skip(6)
            .take(2)
            .all(|r| r == "1.00")),
        "{stdout}"
    );
}
