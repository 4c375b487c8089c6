//! The accelerated GRNN evaluators stay within their stated bounds of the direct
//! sum, on random points inside the data, around it and far outside.

use host_sim::model::hose::data::{DynamicData, QuasiStaticData};
use host_sim::model::hose::fast::{FastGrnn, Truncated};
use host_sim::model::hose::grnn::GrnnHose;
use host_sim::model::hose::local::{LocalCache, LocalGrnn};
use host_sim::model::hose::memory::{features, MemoryGrnn, MEMORY_DIM};
use host_sim::model::hose::net::Grnn;
use rand::{Rng, SeedableRng};

fn pooled(sigma: f64) -> Grnn {
    let d = QuasiStaticData::shipped();
    let (x, y) = d.xy(&(0..d.samples.len()).collect::<Vec<_>>());
    Grnn::fit2(&x, &y, sigma).unwrap()
}

/// A named query box: (name, P range MPa, dP/dt range MPa/s).
type QueryBox = (&'static str, (f64, f64), (f64, f64));

/// Query boxes (P MPa, dP/dt MPa/s): the data, the table margin, beyond it, the
/// plant's transients, and far extrapolation in every direction.
const BOXES: [QueryBox; 6] = [
    ("data", (0.5, 3.5), (-1.1, 1.1)),
    ("margin", (-0.4, 4.4), (-2.5, 2.5)),
    ("beyond", (-1.0, 5.0), (-6.0, 6.0)),
    ("transients", (0.0, 6.0), (-600.0, 600.0)),
    ("far", (-100.0, 100.0), (-1000.0, 1000.0)),
    ("very far", (-1e5, 1e5), (-1e6, 1e6)),
];

#[test]
fn fast_grnn_within_bound_of_direct_sum() {
    let net = pooled(0.1);
    let fast = FastGrnn::new(&net);
    let (lo, hi) = net.output_range();
    let bound = fast.error_bound();
    println!(
        "FastGrnn: {} table nodes, bound {bound:.4} mm^3/s ({:.2e} of the range)",
        fast.table_nodes(),
        bound / (hi - lo)
    );
    // The stated bound is small against the output range (774 mm^3/s).
    assert!(bound > 0.0 && bound < 5e-4 * (hi - lo), "bound {bound}");
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    for (name, p, d) in BOXES {
        let mut worst: f64 = 0.0;
        let mut worst_grad: f64 = 0.0;
        for _ in 0..3000 {
            let q = [rng.random_range(p.0..p.1), rng.random_range(d.0..d.1)];
            let mut g = [0.0; 2];
            let exact = net.predict_with_gradient(&q, &mut g);
            let (v, gf) = fast.eval(q);
            worst = worst.max((v - exact).abs());
            if name != "data" {
                continue;
            }
            // Slope used by Newton: close to the analytic one inside the data.
            worst_grad = worst_grad.max((gf[1] - g[1]).abs() / (1.0 + g[1].abs()));
        }
        println!("{name:>10}: worst |fast - direct| = {worst:.3e} mm^3/s");
        assert!(worst <= bound, "{name}: {worst} > {bound}");
        if name == "data" {
            println!("            worst relative slope error {worst_grad:.3e}");
            assert!(worst_grad < 0.05, "slope error {worst_grad}");
        }
    }
}

/// The truncated sum's bound N e^-T (Y_max - Y_min) is provable; check it with a
/// loose eps (so that the truncation is visible) and the plant's eps.
#[test]
fn truncated_within_provable_bound() {
    let net = pooled(0.1);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(4);
    for eps in [1e-2, 1e-6] {
        let t = Truncated::new(&net, eps);
        let bound = t.error_bound();
        let mut worst: f64 = 0.0;
        let mut summed = 0usize;
        let n = 4000;
        for i in 0..n {
            let (_, p, d) = BOXES[i % BOXES.len()];
            let q = [rng.random_range(p.0..p.1), rng.random_range(d.0..d.1)];
            let u = net.scale_input(&q);
            let e = t.eval_z(&u[..2], false);
            summed += e.n_summed;
            worst = worst.max((e.y - net.predict(&q)).abs());
        }
        println!(
            "eps {eps:e}: bound {bound:.3e}, worst {worst:.3e}, mean samples summed {} of {}",
            summed / n,
            net.len()
        );
        assert!(worst <= bound, "eps {eps}: {worst} > {bound}");
    }
}

/// The memory hose's 4-input truncated evaluator (merged samples) against the
/// direct sum of the same network.
#[test]
fn memory_truncated_within_bound() {
    let d = DynamicData::shipped();
    let runs: Vec<_> = d.runs.iter().collect();
    let m = MemoryGrnn::fit_merged(&runs, [0.01, 0.3], 0.1, 4, 0.05).unwrap();
    let t = Truncated::new(&m.net, 1e-3);
    let bound = t.error_bound();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    let mut worst: f64 = 0.0;
    let f = features(&d.runs[2], [0.01, 0.3]);
    for i in 0..600 {
        // Points of a run, jittered, and random points far outside.
        let row: [f64; MEMORY_DIM] = if i % 3 == 2 {
            [
                rng.random_range(-5.0..10.0),
                rng.random_range(-2e3..2e3),
                rng.random_range(-5.0..5.0),
                rng.random_range(-5.0..5.0),
            ]
        } else {
            let j = rng.random_range(0..d.runs[2].len());
            std::array::from_fn(|k| {
                f[j * MEMORY_DIM + k] * (1.0 + 0.05 * rng.random_range(-1.0..1.0))
            })
        };
        let u = m.net.scale_input(&row);
        let e = t.eval_z(&u[..MEMORY_DIM], false);
        worst = worst.max((e.y - m.net.predict(&row)).abs());
    }
    let (lo, hi) = m.net.output_range();
    println!(
        "memory: bound {bound:.3} mm^3/s (range {:.0}), worst {worst:.3e}",
        hi - lo
    );
    assert!(worst <= bound);
}

/// The plant's default static hose is the pooled GRNN at sigma 0.1 and carries
/// the FastGrnn bound.
#[test]
fn shipped_static_hose() {
    let h = GrnnHose::shipped_static();
    assert_eq!((h.n_samples(), h.sigma()), (2520, 0.1));
    let net = pooled(0.1);
    assert_eq!(h.output_range_mm3ps(), net.output_range());
    for q in [[0.64, 0.0], [3.1, 0.0], [2.0, 0.8], [1.0, -50.0]] {
        let (g, _) = h.wall_rate(q[0], q[1], [0.0; 2]);
        assert!(
            (g - net.predict(&q)).abs() <= h.error_bound_mm3ps(),
            "{q:?}"
        );
    }
}

/// A query of the memory GRNN far from its data (raw inputs: P [MPa],
/// dP/dt [MPa/s], P - P_f1, P - P_f2).
fn far_query(rng: &mut rand_chacha::ChaCha8Rng) -> [f64; MEMORY_DIM] {
    [
        rng.random_range(-5.0..10.0),
        rng.random_range(-2e3..2e3),
        rng.random_range(-5.0..5.0),
        rng.random_range(-5.0..5.0),
    ]
}

/// The memory hose's plant evaluator ([`LocalGrnn`]) against the direct sum of the
/// same network, at two bounds: queries along random walks through the data (as
/// the plant's: small steps, 99 of them between jumps, so that a list is reused
/// while the query drifts and is rebuilt when it has drifted too far) and far
/// outside it, through one cache as in the plant. The value is within the
/// provable bound and, with the slope, bit-identical to an evaluation through a
/// fresh cache (the list only speeds the sum up); the slope's distance to the
/// direct sum's, which the bound does not cover, is printed.
#[test]
fn memory_local_within_bound_of_direct_sum() {
    let d = DynamicData::shipped();
    let runs: Vec<_> = d.runs.iter().collect();
    let m = MemoryGrnn::fit_merged(&runs, [0.01, 0.3], 0.1, 2, 0.05).unwrap();
    let f = features(&d.runs[1], [0.01, 0.3]);
    let rows = f.len() / MEMORY_DIM;
    let (lo, hi) = m.net.output_range();
    let std = m.net.scaler().std.clone();
    for eps in [1e-3, 1e-6] {
        let local = LocalGrnn::new(&m.net, eps);
        let bound = local.error_bound();
        assert!((bound - eps * (hi - lo)).abs() < 1e-9 * (hi - lo));
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(17);
        let mut cache = LocalCache::new();
        let (mut worst, mut worst_far, mut worst_slope) = (0.0f64, 0.0f64, 0.0f64);
        let mut x = [0.0; MEMORY_DIM];
        let (mut jumps, mut far_points) = (0u64, 0u64);
        for i in 0..4000 {
            let far = i % 100 == 99;
            if far {
                x = far_query(&mut rng);
            } else if i % 100 == 0 {
                // Jump to a point of a run (after a far point too).
                let j = rng.random_range(0..rows);
                x.copy_from_slice(&f[j * MEMORY_DIM..(j + 1) * MEMORY_DIM]);
            } else {
                // A small step (z units), mostly in dP/dt (Newton), as the plant's
                // queries.
                for (k, s) in [0.01, 0.03, 0.01, 0.01].iter().enumerate() {
                    x[k] += s * std[k] * rng.random_range(-1.0..1.0);
                }
            }
            if far {
                far_points += 1;
            } else if i % 100 == 0 {
                jumps += 1;
            }
            let u4 = m.net.scale_input(&x);
            let u: [f64; MEMORY_DIM] = core::array::from_fn(|k| u4[k]);
            let e = local.eval_z(&u, &mut cache);
            let fresh = local.eval_z(&u, &mut LocalCache::new());
            assert_eq!(e.y.to_bits(), fresh.y.to_bits(), "query {i}");
            assert_eq!(e.dy_du1.to_bits(), fresh.dy_du1.to_bits(), "query {i}");
            let mut g = [0.0; MEMORY_DIM];
            let exact = m.net.predict_with_gradient(&x, &mut g);
            let err = (e.y - exact).abs();
            if far {
                worst_far = worst_far.max(err);
            } else {
                worst = worst.max(err);
                let slope = g[1] * std[1];
                worst_slope = worst_slope.max((e.dy_du1 - slope).abs() / (1.0 + slope.abs()));
            }
        }
        let s = cache.stats();
        println!(
            "eps {eps:e}: bound {bound:.3e} mm^3/s; worst |local - direct| {worst:.3e} (data), \
             {worst_far:.3e} (far); slope rel {worst_slope:.1e}; per evaluation {:.1} kernels, \
             {:.1} distances; {} rebuilds ({} forced by jumps) of {} evaluations",
            s.kernels as f64 / s.evals as f64,
            s.distances as f64 / s.evals as f64,
            s.rebuilds,
            jumps + far_points,
            s.evals
        );
        assert!(worst <= bound && worst_far <= bound);
        // Lists are reused, and rebuilt by drift too (not only after a jump or a
        // far point), so the comparison with a fresh cache covers stale lists.
        assert!(s.rebuilds < s.evals / 10, "the list is reused");
        assert!(
            s.rebuilds > 2 * (jumps + far_points),
            "drift rebuilds: {} rebuilds, {} jumps",
            s.rebuilds,
            jumps + far_points
        );
    }
}

/// The plant's evaluator with Taylor steps ([`LocalCache::with_taylor`])
/// against the direct sum of the same network, at two bounds: along walks
/// through the data of steps from 1e-6 to 1e-2 (log-uniform, in units of each
/// input's spread), so that queries are served by steps near and far from
/// their anchor and beyond the largest step allowed, with jumps to run points
/// and far points. Every value is within the provable bound (the steps'
/// remainder alone is checked against its own, much tighter bound in
/// `local.rs`'s unit test); most queries are steps; after `forget` the next
/// one is summed, the same to the bit as through a fresh cache.
#[test]
fn memory_taylor_steps_within_bound_of_direct_sum() {
    let d = DynamicData::shipped();
    let runs: Vec<_> = d.runs.iter().collect();
    let m = MemoryGrnn::fit_merged(&runs, [0.01, 0.3], 0.1, 2, 0.05).unwrap();
    let f = features(&d.runs[0], [0.01, 0.3]);
    let rows = f.len() / MEMORY_DIM;
    let std = m.net.scaler().std.clone();
    for eps in [1e-3, 1e-6] {
        let local = LocalGrnn::new(&m.net, eps);
        let bound = local.error_bound();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(23);
        let mut cache = LocalCache::with_taylor();
        let (mut worst_step, mut worst_exact) = (0.0f64, 0.0f64);
        let mut x = [0.0; MEMORY_DIM];
        for i in 0..6000 {
            if i % 200 == 199 {
                x = far_query(&mut rng);
            } else if i % 200 == 0 {
                let j = rng.random_range(0..rows);
                x.copy_from_slice(&f[j * MEMORY_DIM..(j + 1) * MEMORY_DIM]);
            } else {
                let size = 10f64.powf(rng.random_range(-6.0..-2.0));
                for (k, w) in [0.3, 1.0, 0.3, 0.3].iter().enumerate() {
                    x[k] += size * w * std[k] * rng.random_range(-1.0..1.0);
                }
            }
            let u4 = m.net.scale_input(&x);
            let u: [f64; MEMORY_DIM] = core::array::from_fn(|k| u4[k]);
            let before = cache.stats().taylor;
            let e = local.eval_z(&u, &mut cache);
            let err = (e.y - m.net.predict(&x)).abs();
            assert!(err <= bound, "eps {eps:e}, query {i}: {err} > {bound}");
            if cache.stats().taylor > before {
                worst_step = worst_step.max(err);
            } else {
                worst_exact = worst_exact.max(err);
            }
            if i % 500 == 250 {
                // Forgotten: the next query is summed, as through a fresh cache.
                cache.forget();
                let t = cache.stats().taylor;
                let a = local.eval_z(&u, &mut cache);
                let b = local.eval_z(&u, &mut LocalCache::with_taylor());
                assert_eq!(cache.stats().taylor, t);
                assert_eq!(
                    (a.y.to_bits(), a.dy_du1.to_bits()),
                    (b.y.to_bits(), b.dy_du1.to_bits())
                );
            }
        }
        let s = cache.stats();
        let share = s.taylor as f64 / s.evals as f64;
        println!(
            "eps {eps:e}: bound {bound:.3e} mm^3/s; worst |value - direct| {worst_step:.3e} (Taylor \
             steps), {worst_exact:.3e} (summed); {:.1} % of {} evaluations were steps",
            100.0 * share,
            s.evals
        );
        assert!(share > 0.5, "steps {share}");
    }
}
