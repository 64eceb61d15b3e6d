//! Unit tests of particle collisions: pushes against a brute force over every pair, however
//! the pairs were found.

use super::*;

/// Two free particles of different garments at positions `q`, having started the substep at
/// `x`: each one's push.
fn pushes(x: [Vec4; 2], q: [Vec4; 2]) -> [Vec4; 2] {
    let pc = ParticleCollisions {
        radius: 0.01,
        garment: vec![0, 1],
        cell: vec![[0; 3]; 2],
        table: 16,
    };
    let mut grid = pc.grid();
    pc.build(|i| q[i], &mut grid, true);
    let inv_mass = [1.0, 1.0];
    let lists = lists_at(&pc, &q, &grid);
    [0, 1].map(|i| {
        let near = Near::List(&lists[i], q[i]);
        pc.push_out(i, near, (|k| x[k], |k| q[k]), &inv_mass, &grid)
    })
}

/// Every particle's neighbour list at positions `at`, as a remake makes them: each particle's
/// pairs found in `grid` (built at `at` for the lists), then both lists of each pair filled.
fn lists_at(pc: &ParticleCollisions, at: &[Vec4], grid: &Grid) -> Vec<List> {
    let mut pairs = Vec::new();
    for k in 0..at.len() {
        pc.forward_pairs(k, grid, &mut pairs);
    }
    let mut lists = vec![List::EMPTY; at.len()];
    lists_from_pairs(&pairs, &mut lists);
    lists
}

/// `n` free particles of `n` garments (so none are lattice neighbours) in a cube of side
/// `side` [m] around `centre`, by a fixed pseudo-random sequence.
fn cloud(n: usize, side: f32, centre: Vec4, radius: f32) -> (ParticleCollisions, Vec<Vec4>) {
    let mut seed = 0x2545_f491_u32;
    let mut next = || {
        seed ^= seed << 13;
        seed ^= seed >> 17;
        seed ^= seed << 5;
        seed as f32 / u32::MAX as f32 - 0.5
    };
    let points = (0..n)
        .map(|_| centre + Vec4::new(next(), next(), next(), 0.0) * side)
        .collect();
    let pc = ParticleCollisions {
        radius,
        garment: (0..n as u32).collect(),
        cell: vec![[0; 3]; n],
        table: (2 * n).next_power_of_two().max(16),
    };
    (pc, points)
}

/// Each particle's push by brute force over every pair, in ascending order.
fn brute_pushes(pc: &ParticleCollisions, x: &[Vec4], q: &[Vec4]) -> Vec<Vec4> {
    let diameter = pc.diameter();
    (0..q.len())
        .map(|i| {
            let (mut push, mut touching) = (Vec4::ZERO, 0u32);
            for j in 0..q.len() {
                let d = q[i] - q[j];
                let distance = d.length();
                if j == i || distance >= diameter || distance < 1e-9 {
                    continue;
                }
                let along = apart(x[i] - x[j], d, distance);
                push += along * ((diameter - d.dot(along)) * 0.5);
                touching += 1;
            }
            push / touching.max(1) as f32
        })
        .collect()
}

#[test]
fn every_pair_within_a_diameter_is_pushed_wherever_it_lies_in_its_cell() {
    // A cloud dense enough that each particle overlaps several, placed over many offsets
    // from the grid (particles near every side of their cells): the pushes from the lists
    // and from the direct grid both equal the brute force's to the bit. The grid before
    // walked cells one diameter wide and missed a third of the overlapping pairs in P.
    let radius = 0.01;
    for shift in 0..7 {
        let centre = Vec4::new(0.31, -0.7, 1.3, 0.0) + Vec4::splat(shift as f32 * 0.0137);
        let (pc, q) = cloud(300, 0.15, centre, radius);
        let x: Vec<Vec4> = q
            .iter()
            .map(|p| *p + Vec4::new(0.0, 0.001, 0.0, 0.0))
            .collect();
        let (mut for_lists, mut direct) = (pc.grid(), pc.grid());
        pc.build(|i| q[i], &mut for_lists, true);
        pc.build(|i| q[i], &mut direct, false);
        let inv_mass = vec![1.0; q.len()];
        let expected = brute_pushes(&pc, &x, &q);
        let touching = expected.iter().filter(|p| **p != Vec4::ZERO).count();
        assert!(touching > 200, "{touching} particles touch another");
        let lists = lists_at(&pc, &q, &for_lists);
        let (x, q) = (|k: usize| x[k], |k: usize| q[k]);
        for (i, want) in expected.iter().enumerate() {
            let near = Near::List(&lists[i], q(i));
            let got = pc.push_out(i, near, (x, q), &inv_mass, &for_lists);
            assert_eq!(got, *want, "particle {i}, shift {shift}, from its list");
            let got = pc.push_out(i, Near::Grid, (x, q), &inv_mass, &direct);
            assert_eq!(got, *want, "particle {i}, shift {shift}, in the grid");
        }
    }
}

#[test]
fn lists_made_before_the_particles_moved_push_as_fresh_ones_until_stale() {
    // Lists made at `before`, then every particle moved by just under the rebuild
    // threshold in its own direction: the pushes equal fresh lists' (and the brute force's)
    // to the bit, and one move past the threshold makes them stale.
    let radius = 0.01;
    let (pc, before) = cloud(250, 0.14, Vec4::new(-0.2, 0.4, 0.05, 0.0), radius);
    let step = 0.999 * REBUILD_AT * LIST_MARGIN * pc.diameter();
    let (_, directions) = cloud(250, 2.0, Vec4::ZERO, radius);
    let q: Vec<Vec4> = (before.iter().zip(&directions))
        .map(|(p, d)| *p + d.normalize() * step)
        .collect();
    let moved = (q.iter().zip(&before))
        .map(|(a, b)| a.distance(*b))
        .fold(0.0, f32::max);
    assert!(!pc.lists_stale(moved), "moved {moved}");
    assert!(pc.lists_stale(moved * 1.02 / 0.999));
    assert!(pc.lists_stale(f32::NAN));
    let (mut old, mut fresh) = (pc.grid(), pc.grid());
    pc.build(|i| before[i], &mut old, true);
    pc.build(|i| q[i], &mut fresh, true);
    let inv_mass = vec![1.0; q.len()];
    let expected = brute_pushes(&pc, &before, &q);
    assert!(expected.iter().filter(|p| **p != Vec4::ZERO).count() > 100);
    let (kept, new) = (lists_at(&pc, &before, &old), lists_at(&pc, &q, &fresh));
    for i in 0..q.len() {
        let (x, at) = (|k: usize| before[k], |k: usize| q[k]);
        let a = pc.push_out(i, Near::List(&kept[i], before[i]), (x, at), &inv_mass, &old);
        let b = pc.push_out(i, Near::List(&new[i], q[i]), (x, at), &inv_mass, &fresh);
        assert_eq!(a, expected[i], "particle {i}");
        assert_eq!(b, expected[i], "particle {i}");
    }
}

#[test]
fn a_list_too_long_to_keep_walks_the_grid_to_the_same_push() {
    // 60 and 100 particles within 3 cm of each other at a 1 cm radius: every list
    // overflows, and the walk in the grid gives the brute force's pushes (with 100, more
    // than `NEAR` lie near each: the merge of the buckets). Also with a table of 16 buckets,
    // where the rows around a point wrap and share buckets (walked bucket by bucket).
    for n in [60, 100] {
        overflowing(n, None);
        overflowing(n, Some(16));
    }
}

fn overflowing(n: usize, table: Option<usize>) {
    let (mut pc, q) = cloud(n, 0.03, Vec4::new(0.5, 0.5, 0.5, 0.0), 0.01);
    pc.table = table.unwrap_or(pc.table);
    let mut grid = pc.grid();
    pc.build(|i| q[i], &mut grid, true);
    let x: Vec<Vec4> = q.iter().map(|p| *p * 1.01).collect();
    let inv_mass = vec![1.0; q.len()];
    let expected = brute_pushes(&pc, &x, &q);
    let lists = lists_at(&pc, &q, &grid);
    for (i, want) in expected.iter().enumerate() {
        let list = lists[i];
        assert!(list.entries().is_none(), "particle {i}'s list kept");
        let near = Near::List(&list, q[i]);
        let got = pc.push_out(i, near, (|k| x[k], |k| q[k]), &inv_mass, &grid);
        assert_eq!(got, *want, "particle {i}");
    }
}

#[test]
fn lists_that_go_stale_at_once_give_way_to_direct_search_for_a_run() {
    // Stale by more movers than a patch takes (1 000 particles, 100 movers).
    let (n, many) = (1000, 100);
    let made = ListState::default().after(Finding::Remake, false);
    assert_eq!(ListState::default().finding(false, 0, n), Finding::Remake);
    assert_eq!(made.finding(false, 0, n), Finding::Reuse);
    // Stale at the first substep after they were made: direct for DIRECT_RUN substeps,
    // then lists again.
    assert_eq!(made.finding(true, many, n), Finding::Direct);
    let mut state = made.after(Finding::Direct, true);
    for _ in 1..DIRECT_RUN {
        assert_eq!(state.finding(false, 0, n), Finding::Direct);
        state = state.after(Finding::Direct, false);
    }
    assert_eq!(state.finding(false, 0, n), Finding::Remake);
    // Lists that served a substep are made again when stale.
    let served = made.after(Finding::Reuse, false);
    assert_eq!(served.finding(true, many, n), Finding::Remake);
}

#[test]
fn lists_stale_by_a_few_movers_are_patched_until_they_are_many() {
    let n = 1000;
    let few = (n / PATCH_SHARE as usize) as u32;
    let made = ListState::default().after(Finding::Remake, false);
    for state in [made, made.after(Finding::Reuse, false)] {
        assert_eq!(state.finding(true, 1, n), Finding::Patch);
        assert_eq!(state.finding(true, few, n), Finding::Patch);
        assert_ne!(state.finding(true, few + 1, n), Finding::Patch);
    }
    // A patched substep is one more the lists served; never more movers than PATCH_MOVERS.
    let patched = made.after(Finding::Patch, true);
    assert_eq!(patched.finding(true, few + 1, n), Finding::Remake);
    let large = 100 * PATCH_MOVERS as usize * PATCH_SHARE as usize;
    assert_eq!(patched.finding(true, PATCH_MOVERS, large), Finding::Patch);
    assert_eq!(
        patched.finding(true, PATCH_MOVERS + 1, large),
        Finding::Remake
    );
    // Without lists, nothing to patch.
    assert_ne!(ListState::default().finding(true, 1, n), Finding::Patch);
}

#[test]
fn a_particle_carried_through_another_goes_back_to_its_own_side() {
    // Particle 0 started 3 cm above particle 1 and the solve carried it to 5 mm below: the
    // pair ends a diameter (2 cm) apart with 0 above, as it started.
    let x = [Vec4::new(0.0, 0.03, 0.0, 0.0), Vec4::ZERO];
    let q = [Vec4::new(0.0, -0.005, 0.0, 0.0), Vec4::ZERO];
    let p = pushes(x, q);
    let apart = (q[0] + p[0]) - (q[1] + p[1]);
    assert!(
        (apart - Vec4::new(0.0, 0.02, 0.0, 0.0)).length() < 1e-6,
        "{apart}"
    );
}

#[test]
fn an_overlap_without_a_crossing_is_pushed_apart_along_the_start_separation() {
    // Closing along x at a slant: they end a diameter apart along where they came from,
    // each moving half of the overlap.
    let x = [Vec4::new(0.05, 0.0, 0.0, 0.0), Vec4::ZERO];
    let q = [Vec4::new(0.012, 0.004, 0.0, 0.0), Vec4::ZERO];
    let p = pushes(x, q);
    assert!(
        (p[0] - Vec4::new(0.004, 0.0, 0.0, 0.0)).length() < 1e-6,
        "{}",
        p[0]
    );
    assert!((p[1] + p[0]).length() < 1e-6, "{}", p[1]);
}

#[test]
fn memory_bytes_counts_the_buffers_a_simulation_allocates() {
    // The static data and a grid as built, per particle a list, an anchor, a push, two flags,
    // room for a pair and a grid slot, and the movers' list (as `sim::Workspace` allocates them).
    for n in [1, 300, 4148] {
        let (pc, _) = cloud(n, 1.0, Vec4::ZERO, 0.01);
        let grid = pc.grid();
        let allocated = pc.garment.len() * 4
            + pc.cell.len() * 12
            + (grid.start.len() + grid.items.len() + grid.bucket.len() + grid.cursor.len()) * 4
            + (grid.xs.len() + grid.ys.len() + grid.zs.len()) * 4
            + n * (std::mem::size_of::<List>() + 16 + 16)
            + n * std::mem::size_of::<(u32, u32)>()
            + n * 4
            + n * 2
            + PATCH_MOVERS as usize * 4;
        assert_eq!(
            ParticleCollisions::memory_bytes(n),
            allocated,
            "{n} particles"
        );
    }
}

#[test]
fn lists_patched_past_a_few_movers_push_as_the_brute_force() {
    // Lists made at `before`; then most particles moved by just under the rebuild threshold,
    // and a few (the movers) by up to four diameters, some onto others. A patched substep (the
    // movers found apart, the particles they touch marked) gives the brute force's pushes to
    // the bit, for every particle, with lists kept and with lists too long to keep.
    let radius = 0.01;
    for (n, side) in [(250, 0.14), (80, 0.03)] {
        let (pc, before) = cloud(n, side, Vec4::new(0.2, -0.1, 0.4, 0.0), radius);
        let limit = REBUILD_AT * LIST_MARGIN * pc.diameter();
        let (_, directions) = cloud(n, 2.0, Vec4::ZERO, radius);
        let q: Vec<Vec4> = (before.iter().zip(&directions).enumerate())
            .map(|(i, (p, d))| match i % 9 {
                0 => before[(i * 7 + 3) % n] + d.normalize() * 0.3 * pc.diameter(),
                4 => *p + d.normalize() * (1.5 + (i % 5) as f32) * pc.diameter() * 0.5,
                _ => *p + d.normalize() * 0.999 * limit,
            })
            .collect();
        let moving: Vec<bool> = (q.iter().zip(&before))
            .map(|(a, b)| pc.lists_stale(a.truncate().distance(b.truncate())))
            .collect();
        let movers: Vec<u32> = (0..n as u32).filter(|&i| moving[i as usize]).collect();
        assert!(movers.len() >= n / 9, "{} movers", movers.len());
        let mut grid = pc.grid();
        pc.build(|i| before[i], &mut grid, true);
        let lists = lists_at(&pc, &before, &grid);
        let (x, at) = (|k: usize| before[k], |k: usize| q[k]);
        let is_mover = |j: usize| moving[j];
        let mut touched = vec![false; n];
        for &i in &movers {
            pc.touched_by_mover(i as usize, at, &is_mover, &grid, |j| touched[j] = true);
        }
        assert!(
            touched.iter().any(|&t| t),
            "no mover touches a particle that stayed"
        );
        let patch = Patch {
            moving: &is_mover,
            movers: &movers,
        };
        let inv_mass = vec![1.0; n];
        let expected = brute_pushes(&pc, &before, &q);
        let touching = expected.iter().filter(|p| **p != Vec4::ZERO).count();
        assert!(touching > n / 3, "{touching} particles touch another");
        for i in 0..n {
            let near = match moving[i] || touched[i] {
                true => Near::Patched(&lists[i], before[i], patch),
                false => Near::List(&lists[i], before[i]),
            };
            let got = pc.push_out(i, near, (x, at), &inv_mass, &grid);
            assert_eq!(got, expected[i], "particle {i} of {n}, mover {}", moving[i]);
        }
    }
}

/// Each particle's neighbour list by brute force over every pair: the particles but itself and
/// its lattice neighbours nearer than a list's reach, ascending, or `None` past a list's
/// capacity.
fn brute_lists(pc: &ParticleCollisions, at: &[Vec4]) -> Vec<Option<Vec<u32>>> {
    let reach_squared = pc.list_reach() * pc.list_reach();
    (0..at.len())
        .map(|i| {
            let near: Vec<u32> = (0..at.len())
                .filter(|&j| j != i && !pc.joined(i, j))
                .filter(|&j| (at[i] - at[j]).truncate().length_squared() < reach_squared)
                .map(|j| j as u32)
                .collect();
            (near.len() <= LIST_CAPACITY).then_some(near)
        })
        .collect()
}

/// A sheet of `n` × `n` particles of one garment, `spacing` apart at rest, folded over a
/// cylinder so that its two ends lie `gap` apart, face to face: lattice neighbours along it, and
/// particles of the other end across the gap.
fn folded_sheet(
    n: usize,
    spacing: f32,
    gap: f32,
    radius: f32,
    table: usize,
) -> (ParticleCollisions, Vec<Vec4>) {
    let bend = gap / 2.0;
    let flat = (n as f32 * spacing - std::f32::consts::PI * bend) / 2.0;
    let q = (0..n * n)
        .map(|k| {
            let (u, v) = ((k / n) as f32 * spacing, (k % n) as f32 * spacing);
            let (x, y) = if u < flat {
                (u, 0.0)
            } else if u < flat + std::f32::consts::PI * bend {
                let a = (u - flat) / bend;
                (flat + bend * a.sin(), bend - bend * a.cos())
            } else {
                (flat - (u - flat - std::f32::consts::PI * bend), gap)
            };
            Vec4::new(x + 0.013, y - 0.4, v + 0.2, 0.0)
        })
        .collect();
    let pc = ParticleCollisions {
        radius,
        garment: vec![0; n * n],
        cell: (0..n * n)
            .map(|k| [(k / n) as i32, (k % n) as i32, 0])
            .collect(),
        table,
    };
    (pc, q)
}

/// 300 particles in a 3 cm cube (every list too long to keep, and more pairs a particle than
/// [`NEAR`]) and 24 outside it, each a little less than a list's reach from the cube's nearest
/// face: their short lists hold the clump's particles that found them.
fn clump_and_outliers(radius: f32) -> (ParticleCollisions, Vec<Vec4>) {
    let centre = Vec4::new(0.05, 0.0, -0.3, 0.0);
    let (mut pc, mut q) = cloud(300, 0.03, centre, radius);
    let (_, spread) = cloud(24, 0.03, Vec4::ZERO, radius);
    let out = 0.015 + 0.9 * pc.list_reach();
    for (k, s) in spread.iter().enumerate() {
        let mut p = *s;
        p[k % 3] = if k % 2 == 0 { out } else { -out };
        q.push(centre + p);
    }
    pc.garment = (0..q.len() as u32).collect();
    pc.cell = vec![[0; 3]; q.len()];
    pc.table = (2 * q.len()).next_power_of_two();
    (pc, q)
}

#[test]
fn lists_made_from_pairs_found_once_are_the_brute_force_lists() {
    // Each particle finds its pairs in the cells after its own (each pair once), and the pairs
    // fill both lists: the same lists as the brute force over every pair, on a cloud (lists
    // past their capacity included), on a sheet folded onto itself (its lattice neighbours left
    // out, the other layer kept), on a clump where a particle has more pairs than it gathers
    // at once (the particles just outside it list those it finds one by one), and with a
    // table of 16 buckets, where rows of cells wrap past its end and share
    // buckets with each other.
    let radius = 0.01;
    let spacing = 2.0 * radius;
    let folded = |table| folded_sheet(24, spacing, 1.3 * spacing, radius, table);
    let cases = [
        cloud(400, 0.2, Vec4::new(0.31, -0.7, 1.3, 0.0), radius),
        cloud(120, 0.05, Vec4::new(-0.2, 0.1, 0.0, 0.0), radius),
        clump_and_outliers(radius),
        folded(2048),
        folded(16),
        {
            let (mut pc, q) = cloud(300, 0.15, Vec4::ZERO, radius);
            pc.table = 16;
            (pc, q)
        },
    ];
    for (case, (pc, at)) in cases.iter().enumerate() {
        let mut grid = pc.grid();
        pc.build(|i| at[i], &mut grid, true);
        let lists = lists_at(pc, at, &grid);
        let want = brute_lists(pc, at);
        // Something to compare: entries, or lists too long to keep.
        let kept = want
            .iter()
            .map(|l| l.as_ref().map_or(1, |l| l.len()))
            .sum::<usize>();
        assert!(kept > at.len() / 4, "case {case}: {kept} entries");
        for (i, (list, want)) in lists.iter().zip(&want).enumerate() {
            assert_eq!(list.entries(), want.as_deref(), "case {case}, particle {i}");
        }
    }
}

#[test]
fn a_list_takes_each_particle_once_up_to_its_capacity() {
    let mut list = List::EMPTY;
    for j in [9, 3, 9, 7, 3] {
        list.add(j);
    }
    list.settle();
    assert_eq!(list.entries(), Some(&[3, 7, 9][..]));
    let mut full = List::EMPTY;
    (0..LIST_CAPACITY as u32).rev().for_each(|j| full.add(j));
    full.settle();
    assert_eq!(full.entries().map(|e| e.len()), Some(LIST_CAPACITY));
    full.add(99);
    full.settle();
    assert_eq!(full.entries(), None);
}

/// Lists filled stretch by stretch (as every thread of a team fills its own), from the pairs in
/// another order, are the lists filled at once: full lists, lists of too many, empty lists.
#[test]
fn lists_filled_in_stretches_from_pairs_in_any_order_are_the_lists_filled_at_once() {
    let (pc, mut at) = cloud(600, 0.12, Vec4::new(0.3, -1.2, 2.0, 0.0), 0.01);
    // The last 40 far from the rest and from each other: lists that stay empty.
    for (k, p) in at[560..].iter_mut().enumerate() {
        *p += Vec4::new(1.0 + k as f32, 0.0, 0.0, 0.0);
    }
    let mut grid = pc.grid();
    pc.build(|i| at[i], &mut grid, true);
    let mut pairs = Vec::new();
    for k in 0..at.len() {
        pc.forward_pairs(k, &grid, &mut pairs);
    }
    let mut whole = vec![List::EMPTY; at.len()];
    lists_from_pairs(&pairs, &mut whole);
    let entries = |lists: &[List]| {
        lists
            .iter()
            .map(|l| l.entries().map(<[u32]>::to_vec))
            .collect::<Vec<_>>()
    };
    let expected = entries(&whole);
    assert!(expected.iter().any(Option::is_none), "a list of too many");
    assert!(expected
        .iter()
        .any(|e| e.as_ref().is_some_and(|e| e.len() > 2)));
    assert!(expected
        .iter()
        .any(|e| e.as_ref().is_some_and(Vec::is_empty)));
    // The pairs as two threads would leave them: the second's first, each reversed.
    let half = pairs.len() / 2;
    let shuffled: Vec<(u32, u32)> = (pairs[half..].iter().rev())
        .chain(pairs[..half].iter().rev())
        .copied()
        .collect();
    for cuts in [
        vec![0, at.len()],
        vec![0, 211, at.len()],
        vec![0, 1, 300, 599, at.len()],
    ] {
        let mut lists = vec![List::EMPTY; at.len()];
        for w in cuts.windows(2) {
            lists_from_pairs_from(&shuffled, w[0], &mut lists[w[0]..w[1]]);
        }
        assert_eq!(entries(&lists), expected, "stretches {cuts:?}");
    }
}
