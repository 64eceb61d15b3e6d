//! The shell collider's unit tests: the grid and its walks, placement ahead, the response's
//! independence of order, and the collision passes' shortcuts (the lattice's are in `near.rs`).

/// The dense box visits exactly the points of the cells walked, in the order x, y, z and
/// ascending within a cell (the order of the hashed walk without collisions), also where the
/// walk leaves the box; a box with more cells than the table's buckets falls back to the
/// hash, which finds every point the dense box finds; and either grid gathers for a swept test
/// what it walks.
#[test]
fn a_dense_grid_walks_the_cells_in_the_hashed_walks_order() {
    // Starts of two bytes (400 points) and of four (70 000).
    for count in [400, 70_000] {
        dense_walks_in_hashed_order(count);
    }
}

fn dense_walks_in_hashed_order(count: usize) {
    let cell = 0.1;
    // A fixed scatter of points over a 1 × 0.6 × 0.3 m box (a simple linear congruence).
    let mut seed = 12345u32;
    let mut next = || {
        seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        (seed >> 8) as f32 / (1u32 << 24) as f32
    };
    let points: Vec<Vec3> = (0..count)
        .map(|_| Vec3::new(next() - 0.5, next() * 0.6 + 1.0, next() * 0.3 - 0.1))
        .collect();
    let cells: Vec<IVec3> = points.iter().map(|p| cell_index(*p, cell)).collect();
    let ids: Vec<u32> = (0..points.len() as u32).collect();
    let cell_box = cells.iter().fold((IVec3::MAX, IVec3::MIN), |(lo, hi), c| {
        (lo.min(*c), hi.max(*c))
    });
    let mut dense = HashGrid::default();
    dense.build_cells(&cells, &ids, cell_box, cell, 1 << 12);
    let narrow = matches!(
        dense.dense.as_ref().map(|d| &d.start),
        Some(Starts::Narrow(_))
    );
    assert_eq!(
        narrow,
        count <= u16::MAX as usize,
        "10 × 6 × 3 cells fit 4 096 buckets"
    );
    let mut hashed = HashGrid::default();
    hashed.build_cells(&cells, &ids, cell_box, cell, 64);
    assert!(hashed.dense.is_none(), "more cells than 64 buckets: hashed");
    for (a, b) in [
        (Vec3::new(0.0, 1.3, 0.05), Vec3::new(0.0, 1.3, 0.05)),
        (Vec3::new(-0.45, 1.05, -0.09), Vec3::new(-0.3, 1.2, 0.0)),
        (Vec3::new(0.42, 1.55, 0.17), Vec3::new(0.7, 1.9, 0.4)),
        (Vec3::new(2.0, 2.0, 2.0), Vec3::new(2.1, 2.0, 2.0)),
    ] {
        let (lo, hi) = (
            cell_index(a.min(b), cell) - IVec3::ONE,
            cell_index(a.max(b), cell) + IVec3::ONE,
        );
        let mut expected: Vec<usize> = (0..points.len())
            .filter(|&i| cells[i].cmpge(lo).all() && cells[i].cmple(hi).all())
            .collect();
        expected.sort_by_key(|&i| (cells[i].x, cells[i].y, cells[i].z, i));
        let mut seen = Vec::new();
        dense.near_segment(a, b, |i| seen.push(i));
        assert_eq!(seen, expected, "{count} points, path {a} → {b}");
        if count < 1000 {
            let mut found = Vec::new();
            hashed.near_segment(a, b, |i| found.push(i));
            assert!(expected.iter().all(|i| found.contains(i)));
        }
        // Gathered a run at a time (short runs copied whole, long ones and the overflow past
        // `SHELL_FOUND` entry by entry): the walk's points, in its order.
        for grid in [&dense, &hashed] {
            let mut walked = Vec::new();
            grid.near_segment(a, b, |i| walked.push(i as u32));
            let mut found: Found = [std::mem::MaybeUninit::uninit(); SHELL_FOUND + RUN_COPY];
            let n = grid.gather_segment(a, b, &mut found);
            assert_eq!(n, walked.len(), "{count} points, path {a} → {b}");
            let kept = n.min(SHELL_FOUND);
            // SAFETY: `gather_segment` wrote the first `kept` entries.
            let gathered: Vec<u32> = found[..kept]
                .iter()
                .map(|s| unsafe { s.assume_init() })
                .collect();
            assert_eq!(gathered, walked[..kept], "{count} points, path {a} → {b}");
        }
        if a == b {
            let mut around = Vec::new();
            dense.near(a, |i| around.push(i));
            assert_eq!(around, expected, "{count} points, around {a}");
        }
    }
}

#[test]
fn four_normals_at_once_are_each_normalized_to_the_bit() {
    let mut seed = 99u32;
    let mut next = || {
        seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        (seed >> 8) as f32 / (1u32 << 24) as f32 - 0.5
    };
    let mut vectors: Vec<Vec3A> = (0..400)
        .map(|k| Vec3A::new(next(), next(), next()) * 10f32.powi(k % 9 - 4))
        .collect();
    vectors.extend([
        Vec3A::ZERO,
        Vec3A::splat(1e-30),
        Vec3A::splat(f32::MAX),
        Vec3A::new(f32::NAN, 0.0, 1.0),
    ]);
    for four in vectors.chunks_exact(4) {
        let four: [Vec3A; 4] = four.try_into().unwrap();
        let units = normalize4_or_y(four);
        for (v, u) in four.iter().zip(units) {
            let expected = Vec3::from(*v).normalize_or(Vec3::Y);
            assert_eq!(
                Vec3::from(u).to_array().map(f32::to_bits),
                expected.to_array().map(f32::to_bits),
                "{v}"
            );
        }
    }
}

#[test]
fn cell_index_is_floor_for_every_kind_of_value() {
    let values = [
        0.0,
        -0.0,
        0.5,
        -0.5,
        1.0,
        -1.0,
        2.999_999,
        -2.000_001,
        1e9,
        -1e9,
        3e9,
        -3e9,
        f32::MAX,
        f32::MIN,
        f32::INFINITY,
        f32::NEG_INFINITY,
        f32::NAN,
        1e-40,
        -1e-40,
        2_147_483_520.0,
        -2_147_483_520.0,
        2_147_483_648.0,
        -2_147_483_648.0,
        -1.5,
        -7.25,
    ];
    for &x in &values {
        for &cell in &[1.0f32, 0.0125, 3.0] {
            let p = Vec3::new(x, -x, x * 0.37);
            assert_eq!(
                cell_index(p, cell),
                (p / cell).floor().as_ivec3(),
                "{p} / {cell}"
            );
        }
    }
}

use super::*;
use glam::{IVec3, Vec3A};

#[test]
fn a_static_shell_sits_exactly_on_its_frame_whenever_the_bake_starts() {
    // Enough particles for the one-pass advance, and a few for the step-by-step one.
    for n in [PARALLEL_FROM + 3, 5] {
        let frame: Vec<Vec3> = (0..n)
            .map(|i| Vec3::new(0.1 + i as f32 * 1e-3, 0.45 + (i % 7) as f32 * 0.013, -0.3))
            .collect();
        for from in [0.0, 0.35, 185.0] {
            let mut shell = ShellCollider::new("stool".into(), 0.01, 0.0, vec![frame.clone()]);
            shell.advance(from, from + 0.05, 0.0025);
            assert_eq!(shell.now, frame, "{n} particles from frame {from}");
            assert!(shell.motion.iter().all(|m| *m == Vec3::ZERO));
        }
    }
}

/// A focused shell placed ahead during a substep, by one thread or in parts by three, is, when
/// the next substep takes it, what placing it then gives: every focused particle's position,
/// motion and normal, the grid's walks, the box and the fastest motion; a new focus in between
/// leaves it untaken.
#[test]
fn a_shell_placed_ahead_is_the_shell_placed_then() {
    // A sheet of shell particles over 0.6 × 0.6 m sliding and turning over three frames,
    // with normals; the garments cover its middle.
    let n = 80;
    let frame = |f: f32| -> Vec<Vec3> {
        (0..n * n)
            .map(|i| {
                let (u, v) = ((i % n) as f32 / n as f32, (i / n) as f32 / n as f32);
                let bulge = 0.05 * (3.0 * u + f).sin() * (2.0 * v).cos();
                Vec3::new(0.6 * u + 0.01 * f, bulge + 0.02 * f * u, 0.6 * v)
            })
            .collect()
    };
    let mut shell = ShellCollider::new(
        "s".into(),
        0.01,
        0.0,
        (0..3).map(|f| frame(f as f32)).collect(),
    );
    shell.normals = (0..3)
        .map(|f| {
            frame(f as f32)
                .iter()
                .map(|p| (Vec3::Y + 0.1 * *p).normalize())
                .collect()
        })
        .collect();
    let near = NearGarments::new(&[(Vec3::new(0.3, 0.0, 0.3), 0.12)], 0.04);
    let per = 0.1;
    shell.focus(0.0, &near, per);
    let (active, all) = shell.focused().expect("focused");
    assert!(active > 0 && active < all / 2, "{active} of {all}");
    let r = 0.0025;
    shell.advance(0.0, per, r);
    for (refocus, parts) in [(false, 1), (false, 3), (true, 1)] {
        let mut ahead = shell.clone();
        if parts == 1 {
            ahead.place_ahead(2.0 * per, r);
        } else {
            // In parts on threads of their own, the first part's finishing the whole.
            ahead.prepare_ahead();
            let placing = &ahead;
            std::thread::scope(|scope| {
                for part in 1..parts {
                    scope.spawn(move || placing.place_ahead_part(2.0 * per, r, part, parts));
                }
                placing.place_ahead_part(2.0 * per, r, 0, parts);
                while placing.ahead_parts_placed() < parts {
                    std::thread::yield_now();
                }
                placing.finish_ahead(2.0 * per, r);
            });
        }
        if refocus {
            ahead.focus(per, &near, per);
        }
        ahead.advance(per, 2.0 * per, r);
        assert_eq!(ahead.taken_ahead(), if refocus { 0 } else { 1 });
        let mut then = shell.clone();
        if refocus {
            then.focus(per, &near, per);
        }
        then.advance(per, 2.0 * per, r);
        let focus = &then.focus.as_ref().expect("focused").active;
        for &i in focus {
            let i = i as usize;
            assert_eq!(ahead.now[i], then.now[i], "particle {i}");
            assert_eq!(ahead.motion[i], then.motion[i], "particle {i}");
            assert_eq!(ahead.now_normal[i], then.now_normal[i], "particle {i}");
        }
        assert_eq!((ahead.bounds, ahead.fastest), (then.bounds, then.fastest));
        for p in [Vec3::new(0.3, 0.0, 0.3), Vec3::new(0.25, 0.03, 0.38)] {
            let (mut a, mut b) = (Vec::new(), Vec::new());
            ahead.grid.near(p, |i| a.push(i));
            then.grid.near(p, |i| b.push(i));
            assert!(!b.is_empty());
            assert_eq!(a, b, "around {p}");
        }
    }
}

#[test]
fn the_nearest_list_is_the_same_in_any_order_and_counts_a_particle_once() {
    // Equal distances (ties by index), more candidates than the list holds, repeats.
    let candidates: Vec<(u32, f32)> = (0..40u32)
        .map(|i| (i * 7 % 40, ((i * 13 % 9) as f32) * 1e-4))
        .collect();
    let list_of = |order: &mut dyn Iterator<Item = (u32, f32)>| {
        let mut n = Nearest::default();
        order.for_each(|(i, d)| n.insert(i, d));
        (n.list, n.len)
    };
    let forward = list_of(&mut candidates.iter().copied());
    let backward = list_of(&mut candidates.iter().rev().copied());
    let twice = list_of(&mut candidates.iter().chain(&candidates).copied());
    assert_eq!(forward, backward);
    assert_eq!(forward, twice);
    assert_eq!(forward.1, NEARBY);
    let mut sorted = candidates.clone();
    sorted.sort_by(|a, b| (a.1, a.0).partial_cmp(&(b.1, b.0)).unwrap());
    let expected: Vec<u32> = sorted.iter().take(NEARBY).map(|c| c.0).collect();
    assert_eq!(forward.0.to_vec(), expected);
}

#[test]
fn the_response_does_not_depend_on_the_order_of_the_shells_particles() {
    // A moving ball and a floor patch (whose particles share one tangent plane, so paths
    // cross several at the same time), stored in two orders; garment particles thrown at
    // them from all round, with friction: the same displacements to the bit, the same
    // nearby particles, and the same collision passes.
    let (mut points, mut normals) = (Vec::new(), Vec::new());
    let centre = Vec3::new(0.0, 0.16, 0.0);
    for k in 0..400 {
        let y = 1.0 - 2.0 * (k as f32 + 0.5) / 400.0;
        let phi = k as f32 * 2.399_963;
        let n = Vec3::new(
            (1.0 - y * y).sqrt() * phi.cos(),
            y,
            (1.0 - y * y).sqrt() * phi.sin(),
        );
        points.push(centre + 0.1 * n);
        normals.push(n);
    }
    for (i, j) in (0..24).flat_map(|i| (0..24).map(move |j| (i, j))) {
        points.push(Vec3::new(
            -0.1 + 0.009 * i as f32,
            0.0,
            -0.1 + 0.009 * j as f32,
        ));
        normals.push(Vec3::Y);
    }
    let moved: Vec<Vec3> = points
        .iter()
        .map(|p| *p + Vec3::new(0.003, 0.012, -0.002))
        .collect();
    let n = points.len();
    let mut shuffled: Vec<usize> = (0..n).collect();
    shuffled.sort_by_key(|&i| (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 40);
    let build = |order: &[usize]| {
        let pick = |v: &[Vec3]| order.iter().map(|&i| v[i]).collect::<Vec<_>>();
        let mut s = ShellCollider::new("s".into(), 0.01, 0.3, vec![pick(&points), pick(&moved)]);
        s.normals = vec![pick(&normals), pick(&normals)];
        s.advance(0.0, 0.5, 0.0025);
        s
    };
    let identity: Vec<usize> = (0..n).collect();
    let (a, b) = (build(&identity), build(&shuffled));
    let (mut pushed, mut swept) = (0, 0);
    for k in 0..2000 {
        let u = (k as f32 * 0.618_034).fract();
        let v = (k as f32 * 0.754_878).fract();
        let x = Vec4::new(
            -0.12 + 0.24 * u,
            0.002 + 0.3 * v,
            -0.12 + 0.24 * (k as f32 * 0.569_84).fract(),
            0.0,
        );
        let towards =
            (centre.extend(0.0) - x).normalize() * (0.004 + 0.03 * ((k % 7) as f32 / 6.0));
        let d = if k % 3 == 0 {
            Vec4::new(0.001, -0.02, 0.0, 0.0)
        } else {
            towards
        };
        let (mut la, mut lb) = ([u32::MAX; NEARBY], [u32::MAX; NEARBY]);
        let ra = a.resolve(x, d, 0.0025, Some(&mut la));
        let rb = b.resolve(x, d, 0.0025, Some(&mut lb));
        assert_eq!(ra, rb, "path {k} from {x} by {d}");
        let back: Vec<u32> = lb
            .iter()
            .map(|&j| {
                if j == u32::MAX {
                    j
                } else {
                    shuffled[j as usize] as u32
                }
            })
            .collect();
        assert_eq!(la.to_vec(), back, "path {k}");
        let pass = d * 0.8;
        assert_eq!(
            a.resolve_nearby(x, pass, 0.0025, &la),
            b.resolve_nearby(x, pass, 0.0025, &lb)
        );
        pushed += (ra != d) as usize;
        swept += ((ra - d).length() > 0.0125) as usize;
    }
    // The paths do meet the shell, some beyond the end point's reach.
    assert!(
        pushed > 300 && swept > 20,
        "{pushed} pushed, {swept} caught on their way"
    );
}

#[test]
fn a_pass_left_out_by_the_gap_is_the_pass_to_the_bit() {
    // A floor patch of shell particles 9 mm apart; garment particles listed above it, then
    // moved by passes of every size towards it: wherever the gap less the displacement
    // clears the reach, the full pass finds no contact and returns what `untouched` does.
    let points: Vec<Vec3> = (0..30)
        .flat_map(|i| (0..30).map(move |j| Vec3::new(0.009 * i as f32, 0.0, 0.009 * j as f32)))
        .collect();
    let mut s = ShellCollider::new("s".into(), 0.01, 0.3, vec![points.clone(), points]);
    s.normals = vec![vec![Vec3::Y; 900], vec![Vec3::Y; 900]];
    s.advance(0.0, 0.5, 0.0025);
    let (radius, reach) = (0.0025, 0.0125);
    let (mut left_out, mut met) = (0, 0);
    for k in 0..3000 {
        let u = (k as f32 * 0.618_034).fract();
        let v = (k as f32 * 0.754_878).fract();
        let x = Vec4::new(
            0.03 + 0.2 * u,
            0.0126 + 0.02 * v,
            0.03 + 0.2 * (k as f32 * 0.569_84).fract(),
            0.0,
        );
        let mut list = [u32::MAX; NEARBY];
        s.resolve(x, Vec4::ZERO, radius, Some(&mut list));
        if list[0] == u32::MAX {
            continue;
        }
        let gap = s.nearest_listed(x, &list);
        let d = Vec4::new(0.001 * u, -0.02 * (k % 11) as f32 / 10.0, 0.0, 0.0);
        let full = s.resolve_nearby(x, d, radius, &list);
        if gap - d.truncate().length() > reach + 1e-6 {
            assert_eq!(
                full,
                ShellCollider::untouched(x, d),
                "path {k} from {x} by {d}"
            );
            left_out += 1;
        } else if full != ShellCollider::untouched(x, d) {
            met += 1;
        }
    }
    assert!(
        left_out > 500 && met > 500,
        "{left_out} left out, {met} met the shell"
    );
}

/// One shell particle at the origin on a skin facing +Y; a garment particle ends 2 mm under
/// the skin, 5 mm to the side.
fn resolve_under_the_skin(normals: bool) -> Vec3 {
    let mut shell = ShellCollider::new("s".into(), 0.01, 0.0, vec![vec![Vec3::ZERO]]);
    if normals {
        shell.normals = vec![vec![Vec3::Y]];
    }
    shell.advance(0.0, 0.0, 0.0025);
    let x = Vec4::new(0.005, 0.01, 0.0, 0.0);
    let d = Vec4::new(0.0, -0.012, 0.0, 0.0);
    (x + shell.resolve(x, d, 0.0025, None)).truncate()
}

#[test]
fn a_particle_under_the_skin_goes_back_out_along_the_normal() {
    let p = resolve_under_the_skin(true);
    assert!((p.x - 0.005).abs() < 1e-6, "moved sideways: {p}");
    assert!((p.length() - 0.0125).abs() < 1e-6 && p.y > 0.0, "{p}");
    // Without the skin's normal the push follows the line between the centres: deeper in.
    let radial = resolve_under_the_skin(false);
    assert!(radial.y < -0.001, "{radial}");
}

/// Two shell particles on facing skins (normals +Z and −Z) 8 mm apart, offset 6 mm along the
/// skin, closed on a garment particle between them; friction `mu`; both skins moving by `lift`
/// over the substep. Returns where a particle starting at `x` and moved 1 mm along the skin by
/// the solve ends.
fn resolve_in_a_pinch(mu: f32, lift: Vec3) -> (Vec3, Vec3) {
    let jaws = vec![Vec3::new(0.0, 0.0, -0.004), Vec3::new(0.006, 0.0, 0.004)];
    let moved = jaws.iter().map(|p| *p + lift).collect();
    let mut shell = ShellCollider::new("jaws".into(), 0.01, mu, vec![jaws, moved]);
    shell.normals = vec![vec![Vec3::Z, -Vec3::Z]; 2];
    shell.advance(0.0, 1.0, 0.005);
    let x = Vec4::new(0.003, 0.0, 0.0, 0.0);
    let d = Vec4::new(0.001, 0.0, 0.0, 0.0);
    (
        x.truncate(),
        (x + shell.resolve(x, d, 0.005, None)).truncate(),
    )
}

#[test]
fn a_particle_pinched_between_two_skins_is_held_not_squeezed_out_sideways() {
    // Pushed out of each in turn, along the line from the first's centre (it lies above that
    // particle's tangent plane), it would be squeezed 5 mm or more along the skin; held, it
    // stays where it was.
    let (x, p) = resolve_in_a_pinch(0.5, Vec3::ZERO);
    assert!(p.distance(x) < 1e-7, "held at {x}: {p}");
    // Carried by the skins' mean motion.
    let lift = Vec3::new(0.0, 0.002, 0.0);
    let (x, p) = resolve_in_a_pinch(0.5, lift);
    assert!(p.distance(x + lift) < 1e-7, "carried to {}: {p}", x + lift);
    // Without friction the motion the solve wanted along the skin slips through.
    let (x, p) = resolve_in_a_pinch(0.0, Vec3::ZERO);
    let slipped = x + Vec3::new(0.001, 0.0, 0.0);
    assert!(p.distance(slipped) < 1e-7, "slipped to {slipped}: {p}");
    // One skin alone pushes the particle out, as before.
    let mut one = ShellCollider::new(
        "s".into(),
        0.01,
        0.5,
        vec![vec![Vec3::new(0.0, 0.0, -0.004)]],
    );
    one.normals = vec![vec![Vec3::Z]];
    one.advance(0.0, 0.0, 0.005);
    let x = Vec4::new(0.003, 0.0, 0.0, 0.0);
    let q = (x + one.resolve(x, Vec4::ZERO, 0.005, None)).truncate();
    assert!(
        (q - Vec3::new(0.0, 0.0, -0.004)).length() > 0.0149,
        "pushed out: {q}"
    );
}

/// The two-byte starts' running sum, eight at a time, is the running sum entry by entry, for
/// boxes of every length around a multiple of eight, mostly empty or mostly full.
#[test]
fn the_running_sum_of_starts_eight_at_a_time_is_the_plain_one() {
    let mut seed = 12345u32;
    let mut next = || {
        seed = seed.wrapping_mul(1_103_515_245).wrapping_add(12_345);
        seed >> 16
    };
    for len in (0..40).chain([1000, 1001, 1007]) {
        for one_in in [2, 9, 50] {
            let counts: Vec<u16> = (0..len)
                .map(|_| {
                    if next() % one_in == 0 {
                        (next() % 5) as u16
                    } else {
                        0
                    }
                })
                .collect();
            let mut eight = counts.clone();
            <u16 as Start>::running_sum(&mut eight);
            let mut total = 0u16;
            let plain: Vec<u16> = counts
                .iter()
                .map(|&c| {
                    total += c;
                    total
                })
                .collect();
            assert_eq!(eight, plain, "{len} entries, one in {one_in} filled");
        }
    }
}
