//! The paper's hose-model study on the shipped quasi-static data
//! (docs/model.md section 9; the paper's Fig. 9).

use host_sim::model::hose::data::QuasiStaticData;
use host_sim::model::hose::net::{vacc_mean_normalised_pct, vacc_relative_pct, Grnn};
use host_sim::model::hose::split::Shuffle;
use host_sim::studies::grnn::paper::{
    compare_models, cv_sigmas, pooled_scores, section_scores, CompareOptions, PAPER_SEED,
};

/// docs/model.md section 9 quotes one decimal; with numpy's split reproduced bit for
/// bit the only difference left is the rounding of the quote.
const QUOTE_TOL: f64 = 0.05 + 1e-9;

#[test]
fn section_vacc_reproduces_plant_md_with_numpy_split() {
    let d = QuasiStaticData::shipped();
    let s = section_scores(&d, Shuffle::Numpy, PAPER_SEED, 0.1).unwrap();
    let rel = [90.3, 87.8, 89.8];
    let mean = [92.0, 92.1, 92.6];
    for (i, (sec, sc)) in s.iter().enumerate() {
        println!(
            "section {sec}: VAcc {:.2} % (relative), {:.2} % (mean-normalised), RMSE {:.1} mm^3/s",
            sc.vacc_rel_pct, sc.vacc_mean_pct, sc.rmse
        );
        assert!(
            (sc.vacc_rel_pct - rel[i]).abs() <= QUOTE_TOL,
            "section {sec}: {}",
            sc.vacc_rel_pct
        );
        assert!(
            (sc.vacc_mean_pct - mean[i]).abs() <= QUOTE_TOL,
            "section {sec}: {}",
            sc.vacc_mean_pct
        );
    }
}

/// An independent split (ChaCha8) lands within 1-2 points of the quoted values
/// per section (measured: 91.1 / 88.3 / 90.4 and 91.6 / 91.9 / 92.0).
#[test]
fn section_vacc_with_another_split_is_close() {
    let d = QuasiStaticData::shipped();
    let s = section_scores(&d, Shuffle::ChaCha, PAPER_SEED, 0.1).unwrap();
    for ((_, sc), (r, m)) in s.iter().zip([(90.3, 92.0), (87.8, 92.1), (89.8, 92.6)]) {
        println!(
            "ChaCha split: {:.2} / {:.2}",
            sc.vacc_rel_pct, sc.vacc_mean_pct
        );
        assert!((sc.vacc_rel_pct - r).abs() < 2.0);
        assert!((sc.vacc_mean_pct - m).abs() < 2.0);
    }
}

#[test]
fn pooled_grnn_reproduces_plant_md() {
    let d = QuasiStaticData::shipped();
    let s = pooled_scores(
        &d,
        Shuffle::Numpy,
        PAPER_SEED,
        &[0.01, 0.02, 0.03, 0.04, 0.05, 0.07, 0.1],
    )
    .unwrap();
    for (sig, sc) in &s {
        println!("pooled sigma {sig}: VAcc {:.2} %", sc.vacc_rel_pct);
    }
    let at = |sig: f64| s.iter().find(|p| p.0 == sig).unwrap().1.vacc_rel_pct;
    assert!((at(0.1) - 79.4).abs() <= QUOTE_TOL);
    assert!((at(0.03) - 84.4).abs() <= QUOTE_TOL);
    let best = s
        .iter()
        .max_by(|a, b| a.1.vacc_rel_pct.total_cmp(&b.1.vacc_rel_pct))
        .unwrap();
    assert_eq!(best.0, 0.03);
}

/// 5-fold CV on each section's training part picks sigma = 0.1 (docs/model.md section
/// 9), on all samples pooled a much smaller one (0.04 with these folds; the
/// test-set optimum is 0.03).
#[test]
fn cross_validated_sigma() {
    let d = QuasiStaticData::shipped();
    let cv = cv_sigmas(&d, Shuffle::Numpy, PAPER_SEED).unwrap();
    for (g, r) in &cv {
        println!("{g:?}: CV sigma {}", r.sigma);
    }
    for (g, r) in &cv {
        match g {
            Some(_) => assert_eq!(r.sigma, 0.1),
            None => assert!(
                (0.03..=0.05).contains(&r.sigma),
                "pooled CV sigma {}",
                r.sigma
            ),
        }
    }
}

/// Fig. 9: GRNN, RBF and BP side by side; the GRNN is the most accurate model in
/// every section (as the paper reports), and every model is a useful fit.
#[test]
fn model_comparison_table_and_plot() {
    let d = QuasiStaticData::shipped();
    let c = compare_models(&d, &CompareOptions::default()).unwrap();
    println!("{}", c.table());
    assert_eq!(c.models, ["GRNN", "RBF", "BP"]);
    for s in 0..3 {
        let g = c.scores[0][s].vacc_rel_pct;
        for m in 1..3 {
            let o = c.scores[m][s].vacc_rel_pct;
            assert!(g > o, "section {s}: GRNN {g} vs {} {o}", c.models[m]);
            assert!(o > 80.0, "{} section {s}: {o}", c.models[m]);
        }
    }
    assert_eq!(c.predictions[0].len(), 3 * 168);
    let path = std::env::temp_dir().join(format!("grnn-fig9-{}.png", std::process::id()));
    c.plot(&path).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    assert!(
        bytes.len() > 10_000 && bytes.starts_with(b"\x89PNG"),
        "{} bytes",
        bytes.len()
    );
    std::fs::remove_file(&path).ok();
}

#[test]
fn vacc_definitions() {
    // Relative: samples below 5 % of max |VT| are skipped.
    let t = [100.0, -200.0, 5.0];
    let p = [90.0, -180.0, 500.0];
    assert!((vacc_relative_pct(&t, &p) - 90.0).abs() < 1e-12);
    // Mean-normalised: 1 - (10 + 20 + 495) / 305.
    assert!((vacc_mean_normalised_pct(&t, &p) - 100.0 * (1.0 - 525.0 / 305.0)).abs() < 1e-12);
}

/// The GRNN's defining properties: it interpolates a lone sample exactly, its
/// output is a convex combination of the training outputs, it stays finite far
/// from the data, and its analytic gradient matches finite differences.
#[test]
fn grnn_properties() {
    let d = QuasiStaticData::shipped();
    let (x, y) = d.xy(&d.section_indices(1));
    let net = Grnn::fit2(&x, &y, 0.1).unwrap();
    let (lo, hi) = net.output_range();
    for q in [[2.0, 0.3], [1.7, -0.9], [-100.0, 1e4], [1e6, -1e6]] {
        let v = net.predict(&q);
        assert!(v.is_finite() && v >= lo && v <= hi, "{q:?}: {v}");
    }
    // Far away the nearest sample dominates (here: the one with the largest P).
    let far = net.predict(&[1e3, 0.0]);
    let i = (0..x.len())
        .max_by(|&a, &b| x[a][0].total_cmp(&x[b][0]))
        .unwrap();
    assert_eq!(far, y[i]);
    let mut g = [0.0; 2];
    let q = [2.1, 0.4];
    let v = net.predict_with_gradient(&q, &mut g);
    assert!((v - net.predict(&q)).abs() < 1e-9);
    for k in 0..2 {
        let h = 1e-6;
        let mut a = q;
        let mut b = q;
        a[k] += h;
        b[k] -= h;
        let fd = (net.predict(&a) - net.predict(&b)) / (2.0 * h);
        assert!(
            (g[k] - fd).abs() <= 1e-5 * (1.0 + fd.abs()),
            "d/dx{k}: {} vs {fd}",
            g[k]
        );
    }
    // One sample: the GRNN returns it everywhere.
    assert!(
        Grnn::fit2(&[[1.0, 2.0]], &[3.0], 0.1).is_err(),
        "constant inputs have no z-score"
    );
    let two = Grnn::fit2(&[[1.0, 2.0], [2.0, 3.0]], &[3.0, 5.0], 0.1).unwrap();
    assert!((two.predict(&[1.0, 2.0]) - 3.0).abs() < 1e-12);
}
