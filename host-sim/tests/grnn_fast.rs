//! The accelerated GRNN evaluators stay within their stated bounds of the direct
//! sum, on random points inside the data, around it and far outside.

use host_sim::model::hose::data::{DynamicData, QuasiStaticData};
use host_sim::model::hose::fast::{FastGrnn, Truncated};
use host_sim::model::hose::grnn::GrnnHose;
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
