//! The diagnosis: gap of the nominal model, where it lies, which effect
//! removes it (fitted on the fit runs), and how much on the check runs.

use std::collections::BTreeMap;
use std::time::Instant;

use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;
use serde::Serialize;

use super::fit::{minimize, Bound};
use super::replay::{measured, replay, Replay, CHANNELS};
use super::segment::{labels, Label};
use super::stats::{band_shares, independence, noise_sigma, whiteness, BANDS_HZ};
use crate::effects::{EffectKind, Effects};
use crate::plant::Plant;
use crate::rig::Rig;
use crate::runlog::RunLog;

/// One sentence for the report: what the gap measures.
pub const GAP_METRIC: &str = "RMS over the channels xo_m, xi_m, p1_pa, p2_pa of the 10 ms block mean of \
the residual (measured minus the nominal model replayed on the recorded drive command and load), its \
expected white-noise part removed, each in units of that channel's noise level estimated from the \
log (dimensionless; 0 = agreement within the noise)";

/// Samples per block of the block-mean residual.
pub const BLOCK: usize = 10;
/// Lowest channel scales (noise floors) in SI: Xo 5 um, Xi 1 um, P 1 kPa.
pub const SCALE_FLOOR: [f64; 4] = [5e-6, 1e-6, 1e3, 1e3];
/// Nominal gap (pooled over all runs) below which the verdict is `none`.
pub const NONE_GAP: f64 = 1.0;
/// Smallest shrink, on the fit and on the check runs, that explains a gap.
pub const MIN_SHRINK: f64 = 0.3;
/// Extra shrink of the remaining gap a second effect must give (fit and check).
pub const SECOND_SHRINK: f64 = 0.3;

/// Options of a diagnosis.
#[derive(Clone, Debug)]
pub struct Options {
    /// Largest plant step of the replays, s.
    pub dt_s: f64,
    /// Objective evaluations per candidate fit.
    pub max_evals: usize,
    /// Show a progress bar.
    pub progress: bool,
    /// Try a second effect on top of the best one.
    pub second_effect: bool,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            dt_s: 2e-4,
            max_evals: 36,
            progress: false,
            second_effect: true,
        }
    }
}

/// Before, after and shrink of one set of runs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Shrink {
    /// Gap of the nominal model.
    pub before: f64,
    /// Gap with the effect added.
    pub after: f64,
    /// 1 - after / before.
    pub shrink: f64,
}

impl Shrink {
    fn new(before: f64, after: f64) -> Self {
        let shrink = if before > 0.0 {
            1.0 - after / before
        } else {
            0.0
        };
        Self {
            before,
            after,
            shrink,
        }
    }
}

/// One candidate effect with its fitted parameters.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Candidate {
    /// Identifier of plant.md section 12.
    pub effect: String,
    /// Fitted parameters, names with units.
    pub params: BTreeMap<String, f64>,
    /// Shrink on the fit runs.
    pub fit_shrink: f64,
    /// Shrink on the check runs.
    pub check_shrink: f64,
    /// Gap with the effect on the fit runs.
    pub fit_after: f64,
    /// Gap with the effect on the check runs.
    pub check_after: f64,
    /// Objective evaluations the fit used.
    pub evals: usize,
}

/// A part of a run that carries the gap.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Where {
    /// Channel.
    pub channel: String,
    /// Run (file name).
    pub run: String,
    /// Start, s.
    pub t0_s: f64,
    /// End, s.
    pub t1_s: f64,
    /// Segment label.
    pub label: String,
    /// Fraction of that run's gap inside this part.
    pub share: f64,
}

/// Residual tests and spectrum of one channel of one run (nominal model).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ChannelReport {
    /// Run (file name).
    pub run: String,
    /// Channel.
    pub channel: String,
    /// This channel's gap (same unit as the total).
    pub gap: f64,
    /// Noise level estimated from the log, SI.
    pub noise: f64,
    /// RMS residual, SI.
    pub rms_residual: f64,
    /// Whiteness test passes at 99 %.
    pub white: bool,
    /// Portmanteau statistic of the whiteness test and its 99 % limit.
    pub whiteness_q: [f64; 2],
    /// Residual independent of the drive command at 99 %.
    pub independent_of_input: bool,
    /// Portmanteau statistic of the independence test and its 99 % limit.
    pub independence_q: [f64; 2],
    /// Share of the residual power per band (bands in `bands_hz`).
    pub band_shares: [f64; 4],
}

/// A second effect on top of the verdict's.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Second {
    /// Identifier.
    pub effect: String,
    /// Its fitted parameters.
    pub params: BTreeMap<String, f64>,
    /// Extra shrink of the remaining gap on the fit runs.
    pub fit_extra_shrink: f64,
    /// Extra shrink of the remaining gap on the check runs.
    pub check_extra_shrink: f64,
    /// Whether it adds significantly (both extra shrinks >= the threshold).
    pub significant: bool,
}

/// The diagnosis (the JSON of interfaces.md section 2 and more).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Diagnosis {
    /// Effect identifier, `none` or `unexplained`.
    pub verdict: String,
    /// What the gap measures.
    pub gap_metric: String,
    /// Fit runs: before, after, shrink.
    pub fit: Shrink,
    /// Check runs: before, after, shrink.
    pub check: Shrink,
    /// Every effect tried, best first.
    pub candidates: Vec<Candidate>,
    /// Parts of the runs that carry the gap, largest share first.
    #[serde(rename = "where")]
    pub where_: Vec<Where>,
    /// A second effect, when one was tested.
    pub second_effect: Option<Second>,
    /// Per run and channel: residual tests and spectrum.
    pub channels: Vec<ChannelReport>,
    /// Band edges of `band_shares`, Hz.
    pub bands_hz: Vec<[f64; 2]>,
    /// Why the verdict.
    pub reason: String,
    /// Wall time, s.
    pub elapsed_s: f64,
}

/// One run prepared for the diagnosis: the log, its noise scales and labels.
pub struct Run {
    /// Display name.
    pub name: String,
    /// The log.
    pub log: RunLog,
    /// Noise level per channel.
    pub noise: [f64; 4],
    /// Scale per channel (noise with floor).
    pub scale: [f64; 4],
    /// Segment label per sample.
    pub labels: Vec<Label>,
}

impl Run {
    /// Prepare a log.
    pub fn new(name: String, log: RunLog) -> Self {
        let m = measured(&log);
        let noise: [f64; 4] = std::array::from_fn(|c| noise_sigma(m[c]));
        let scale = std::array::from_fn(|c| noise[c].max(SCALE_FLOOR[c]));
        let labels = labels(&log);
        Self {
            name,
            log,
            noise,
            scale,
            labels,
        }
    }
}

/// Block-mean normalised residuals of one channel and their noise-free
/// excess power per block.
fn block_excess(run: &Run, sim: &Replay, c: usize) -> Vec<f64> {
    let meas = measured(&run.log)[c];
    let s2 = run.scale[c] * run.scale[c];
    let noise_part = run.noise[c] * run.noise[c] / BLOCK as f64;
    meas.chunks(BLOCK)
        .zip(sim.ch[c].chunks(BLOCK))
        .map(|(m, s)| {
            let r = m.iter().zip(s).map(|(a, b)| a - b).sum::<f64>() / m.len() as f64;
            if r.is_finite() {
                (r * r - noise_part) / s2
            } else {
                1e12
            }
        })
        .collect()
}

/// Per-channel excess power (mean over blocks, >= 0) of one run.
fn channel_excess(run: &Run, sim: &Replay) -> [f64; 4] {
    std::array::from_fn(|c| {
        let b = block_excess(run, sim, c);
        (b.iter().sum::<f64>() / b.len().max(1) as f64).max(0.0)
    })
}

/// Pooled gap of several runs from their per-channel excess powers.
fn pooled(excess: &[[f64; 4]], lens: &[usize]) -> f64 {
    let total: usize = lens.iter().sum();
    if total == 0 {
        return 0.0;
    }
    let mut acc = 0.0;
    for (e, n) in excess.iter().zip(lens) {
        acc += e.iter().sum::<f64>() / 4.0 * *n as f64;
    }
    (acc / total as f64).sqrt()
}

/// The rig of a candidate; `None` when the effects cannot go on this plant.
fn rig_with(base: &Plant, effects: &Effects) -> Option<Rig> {
    Rig::new(base.clone(), *effects).ok()
}

/// Gap of `runs` under `effects`.
fn gap(runs: &[Run], base: &Plant, effects: &Effects, dt_s: f64) -> f64 {
    let Some(rig) = rig_with(base, effects) else {
        return f64::INFINITY;
    };
    let ex: Vec<[f64; 4]> = runs
        .iter()
        .map(|r| channel_excess(r, &replay(&r.log, &rig, dt_s)))
        .collect();
    let lens: Vec<usize> = runs.iter().map(|r| r.log.len()).collect();
    pooled(&ex, &lens)
}

/// Fit the parameters of `kind` (on top of `fixed`) on `runs`.
fn fit_effect(
    runs: &[Run],
    base: &Plant,
    fixed: &Effects,
    kind: EffectKind,
    opts: &Options,
) -> (Effects, f64, usize) {
    let specs = kind.params();
    let bounds: Vec<Bound> = specs
        .iter()
        .map(|p| Bound {
            lo: p.min,
            hi: p.max,
        })
        .collect();
    let x0: Vec<f64> = specs.iter().map(|p| p.typical).collect();
    let mut objective = |x: &[f64]| {
        let mut e = *fixed;
        e.set(kind, Some(x));
        if e.validate().is_err() {
            return f64::INFINITY;
        }
        gap(runs, base, &e, opts.dt_s)
    };
    let scan = if specs.len() == 1 { 9 } else { 5 };
    let r = minimize(&mut objective, &bounds, &x0, scan, opts.max_evals);
    let mut e = *fixed;
    e.set(kind, Some(&r.x));
    (e, r.value, r.evals)
}

fn params_map(e: &Effects, kind: EffectKind) -> BTreeMap<String, f64> {
    kind.params()
        .iter()
        .zip(e.get(kind).unwrap_or_default())
        .map(|(p, v)| (p.name.to_string(), v))
        .collect()
}

fn where_list(runs: &[&Run], sims: &[Replay]) -> Vec<Where> {
    let mut out = Vec::new();
    for (run, sim) in runs.iter().zip(sims) {
        let dt = run.log.dt_s();
        let per_ch: Vec<Vec<f64>> = (0..4).map(|c| block_excess(run, sim, c)).collect();
        let total: f64 = per_ch.iter().flatten().map(|x| x.max(0.0)).sum();
        if total <= 0.0 {
            continue;
        }
        for (c, blocks) in per_ch.iter().enumerate() {
            // Group consecutive blocks by the label at their centre.
            let mut i = 0;
            while i < blocks.len() {
                let lab = run.labels[(i * BLOCK + BLOCK / 2).min(run.labels.len() - 1)];
                let mut j = i;
                let mut sum = 0.0;
                while j < blocks.len()
                    && run.labels[(j * BLOCK + BLOCK / 2).min(run.labels.len() - 1)] == lab
                {
                    sum += blocks[j].max(0.0);
                    j += 1;
                }
                let share = sum / total;
                if share >= 0.01 {
                    out.push(Where {
                        channel: CHANNELS[c].to_string(),
                        run: run.name.clone(),
                        t0_s: run.log.t_s[0] + (i * BLOCK) as f64 * dt,
                        t1_s: run.log.t_s[0] + ((j * BLOCK).min(run.log.len())) as f64 * dt,
                        label: lab.name().to_string(),
                        share,
                    });
                }
                i = j;
            }
        }
    }
    out.sort_by(|a, b| b.share.total_cmp(&a.share));
    out.truncate(12);
    out
}

fn channel_reports(runs: &[&Run], sims: &[Replay]) -> Vec<ChannelReport> {
    let mut out = Vec::new();
    for (run, sim) in runs.iter().zip(sims) {
        let ex = channel_excess(run, sim);
        let meas = measured(&run.log);
        for c in 0..4 {
            let r: Vec<f64> = meas[c]
                .iter()
                .zip(&sim.ch[c])
                .map(|(a, b)| a - b)
                .map(|x| if x.is_finite() { x } else { 0.0 })
                .collect();
            let w = whiteness(&r, 25);
            let ind = independence(&run.log.vcmd_mps, &r, 25);
            out.push(ChannelReport {
                run: run.name.clone(),
                channel: CHANNELS[c].to_string(),
                gap: ex[c].sqrt(),
                noise: run.noise[c],
                rms_residual: super::stats::rms(&r),
                white: w.passes(),
                whiteness_q: [w.q, w.q_limit],
                independent_of_input: ind.passes(),
                independence_q: [ind.q, ind.q_limit],
                band_shares: band_shares(&r, run.log.dt_s()),
            });
        }
    }
    out
}

/// Everything the report needs besides the JSON: replays before and after.
pub struct Details {
    /// The fit runs.
    pub fit: Vec<Run>,
    /// The check runs.
    pub check: Vec<Run>,
    /// Nominal replays (fit then check).
    pub before: Vec<Replay>,
    /// Replays with the verdict's effect (fit then check), if any.
    pub after: Vec<Replay>,
    /// The verdict's effects.
    pub effects: Effects,
}

/// Diagnose: fit runs, check runs, the nominal plant.
pub fn diagnose(
    fit: Vec<Run>,
    check: Vec<Run>,
    base: &Plant,
    opts: &Options,
) -> (Diagnosis, Details) {
    let t0 = Instant::now();
    let none = Effects::NONE;
    let sims = |runs: &[Run], e: &Effects| -> Vec<Replay> {
        match rig_with(base, e) {
            Some(rig) => runs
                .iter()
                .map(|r| replay(&r.log, &rig, opts.dt_s))
                .collect(),
            None => Vec::new(),
        }
    };
    let before_fit = gap(&fit, base, &none, opts.dt_s);
    let before_check = gap(&check, base, &none, opts.dt_s);
    let all: Vec<&Run> = fit.iter().chain(check.iter()).collect();
    let nominal: Vec<Replay> = sims(&fit, &none)
        .into_iter()
        .chain(sims(&check, &none))
        .collect();
    let lens: Vec<usize> = all.iter().map(|r| r.log.len()).collect();
    let pooled_all = pooled(
        &all.iter()
            .zip(&nominal)
            .map(|(r, s)| channel_excess(r, s))
            .collect::<Vec<_>>(),
        &lens,
    );
    let where_ = where_list(&all, &nominal);
    let channels = channel_reports(&all, &nominal);
    let mut diag = Diagnosis {
        verdict: "none".into(),
        gap_metric: GAP_METRIC.into(),
        fit: Shrink::new(before_fit, before_fit),
        check: Shrink::new(before_check, before_check),
        candidates: Vec::new(),
        where_,
        second_effect: None,
        channels,
        bands_hz: BANDS_HZ
            .iter()
            .map(|(a, b)| [*a, if b.is_finite() { *b } else { 0.5 / 1e-3 }])
            .collect(),
        reason: String::new(),
        elapsed_s: 0.0,
    };
    let mut details = Details {
        before: nominal,
        after: Vec::new(),
        effects: none,
        fit: Vec::new(),
        check: Vec::new(),
    };
    // Candidates: every effect, fitted on the fit runs, evaluated on the check runs.
    let bar = if opts.progress {
        ProgressBar::new(EffectKind::ALL.len() as u64)
    } else {
        ProgressBar::hidden()
    };
    bar.set_style(
        ProgressStyle::with_template(
            "{spinner} [{elapsed_precise}] {bar:30} {pos}/{len} candidate effects {msg}",
        )
        .expect("valid template"),
    );
    let mut cands: Vec<(Candidate, Effects)> = EffectKind::ALL
        .par_iter()
        .map(|&k| {
            let (e, after_fit, evals) = fit_effect(&fit, base, &none, k, opts);
            let after_check = gap(&check, base, &e, opts.dt_s);
            bar.inc(1);
            bar.set_message(k.name());
            (
                Candidate {
                    effect: k.name().to_string(),
                    params: params_map(&e, k),
                    fit_shrink: Shrink::new(before_fit, after_fit).shrink,
                    check_shrink: Shrink::new(before_check, after_check).shrink,
                    fit_after: after_fit,
                    check_after: after_check,
                    evals,
                },
                e,
            )
        })
        .collect();
    bar.finish_and_clear();
    cands.sort_by(|a, b| b.0.fit_shrink.total_cmp(&a.0.fit_shrink));
    diag.candidates = cands.iter().map(|c| c.0.clone()).collect();
    let best = cands[0].clone();
    if pooled_all < NONE_GAP {
        diag.reason = format!(
            "the nominal model agrees with the runs within their noise (pooled gap {pooled_all:.2} < {NONE_GAP})"
        );
    } else if best.0.fit_shrink < MIN_SHRINK || best.0.check_shrink < MIN_SHRINK {
        diag.verdict = "unexplained".into();
        diag.reason = format!(
            "gap {pooled_all:.2} beyond the noise; the best candidate ({}) shrinks it by {:.0} % on the fit runs and {:.0} % on the check runs (< {:.0} %)",
            best.0.effect,
            best.0.fit_shrink * 100.0,
            best.0.check_shrink * 100.0,
            MIN_SHRINK * 100.0
        );
    } else {
        diag.verdict = best.0.effect.clone();
        diag.fit = Shrink::new(before_fit, best.0.fit_after);
        diag.check = Shrink::new(before_check, best.0.check_after);
        diag.reason = format!(
            "{} shrinks the gap by {:.0} % on the fit runs and {:.0} % on the held-out check runs; the next candidate ({}) by {:.0} % / {:.0} %",
            best.0.effect,
            best.0.fit_shrink * 100.0,
            best.0.check_shrink * 100.0,
            cands.get(1).map(|c| c.0.effect.as_str()).unwrap_or("-"),
            cands.get(1).map(|c| c.0.fit_shrink * 100.0).unwrap_or(0.0),
            cands.get(1).map(|c| c.0.check_shrink * 100.0).unwrap_or(0.0)
        );
        details.effects = best.1;
        if opts.second_effect {
            let k1 = EffectKind::by_name(&best.0.effect).expect("known effect");
            let seconds: Vec<(EffectKind, Effects, f64)> = EffectKind::ALL
                .par_iter()
                .filter(|k| **k != k1)
                .map(|&k| {
                    let (e, after, _) = fit_effect(&fit, base, &best.1, k, opts);
                    (k, e, after)
                })
                .collect();
            if let Some((k2, e2, after_fit2)) =
                seconds.into_iter().min_by(|a, b| a.2.total_cmp(&b.2))
            {
                let after_check2 = gap(&check, base, &e2, opts.dt_s);
                let fit_extra = Shrink::new(best.0.fit_after, after_fit2).shrink;
                let check_extra = Shrink::new(best.0.check_after, after_check2).shrink;
                diag.second_effect = Some(Second {
                    effect: k2.name().to_string(),
                    params: params_map(&e2, k2),
                    fit_extra_shrink: fit_extra,
                    check_extra_shrink: check_extra,
                    significant: fit_extra >= SECOND_SHRINK && check_extra >= SECOND_SHRINK,
                });
            }
        }
    }
    details.after = if details.effects.is_none() {
        Vec::new()
    } else {
        sims(&fit, &details.effects)
            .into_iter()
            .chain(sims(&check, &details.effects))
            .collect()
    };
    details.fit = fit;
    details.check = check;
    diag.elapsed_s = t0.elapsed().as_secs_f64();
    (diag, details)
}
