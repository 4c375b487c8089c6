//! Direct ("naive") vs accelerated GRNN evaluation of the plant's static hose map
//! g(P, dP/dt), side by side, on three query sets: inside the data, around it
//! (the table margin and just beyond) and far outside (the transients of the
//! plant, |dP/dt| up to 300 MPa/s). Prints the speed-up of each set.
//!
//! `cargo bench -p host-sim --bench grnn`

use std::hint::black_box;
use std::time::Instant;

use criterion::{criterion_main, Criterion};
use host_sim::model::hose::data::QuasiStaticData;
use host_sim::model::hose::fast::FastGrnn;
use host_sim::model::hose::net::Grnn;
use rand::{Rng, SeedableRng};

fn query_sets() -> Vec<(&'static str, Vec<[f64; 2]>)> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    let mut set = |p: (f64, f64), d: (f64, f64)| -> Vec<[f64; 2]> {
        (0..256)
            .map(|_| [rng.random_range(p.0..p.1), rng.random_range(d.0..d.1)])
            .collect()
    };
    vec![
        ("inside", set((0.5, 3.5), (-1.0, 1.0))),
        ("around", set((0.0, 4.0), (-3.0, 3.0))),
        ("far", set((0.0, 4.0), (-300.0, 300.0))),
    ]
}

fn bench(c: &mut Criterion) {
    let d = QuasiStaticData::shipped();
    let (x, y) = d.xy(&(0..d.samples.len()).collect::<Vec<_>>());
    let net = Grnn::fit2(&x, &y, 0.1).expect("fit");
    let fast = FastGrnn::new(&net);
    let mut g = c.benchmark_group("grnn");
    for (name, pts) in query_sets() {
        g.bench_function(format!("{name}/naive"), |b| {
            b.iter(|| pts.iter().map(|p| net.predict(black_box(p))).sum::<f64>())
        });
        g.bench_function(format!("{name}/fast"), |b| {
            b.iter(|| pts.iter().map(|p| fast.predict(black_box(*p))).sum::<f64>())
        });
    }
    g.finish();
    // The ratio, measured directly on the same sets (criterion reports each
    // function on its own).
    println!(
        "speed-up of FastGrnn over the direct sum (error bound {:.3} mm^3/s):",
        fast.error_bound()
    );
    for (name, pts) in query_sets() {
        let time = |f: &dyn Fn() -> f64| {
            let t = Instant::now();
            let mut s = 0.0;
            for _ in 0..20 {
                s += f();
            }
            black_box(s);
            t.elapsed().as_secs_f64()
        };
        let tn = time(&|| pts.iter().map(|p| net.predict(black_box(p))).sum());
        let tf = time(&|| pts.iter().map(|p| fast.predict(black_box(*p))).sum());
        println!(
            "  {name:>6}: naive {:8.0} ns, fast {:6.0} ns per evaluation, ratio {:6.1}",
            tn * 1e9 / (20.0 * pts.len() as f64),
            tf * 1e9 / (20.0 * pts.len() as f64),
            tn / tf
        );
    }
}

// criterion's macro defines an undocumented public function.
#[allow(missing_docs)]
mod group {
    criterion::criterion_group!(benches, super::bench);
}
use group::benches;
criterion_main!(benches);
