//! The diagnosis: gap of the nominal model, where it lies, which effect
//! removes it (fitted on the fit runs), and how much on the check runs.

use std::collections::BTreeMap;
use std::time::Instant;

use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;
use serde::Serialize;

use super::fit::{minimize, Bound};
use super::prefit;
use super::replay::{filtered_load, measured, replay_visit, replay_with_load, Replay, CHANNELS};
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
    /// Largest plant step of the replays, s. 5e-4 s keeps RK4 stable (the
    /// fastest eigenvalue of the plant, about -4700 1/s, gives |lambda h| = 2.3
    /// < 2.78) and changes the gaps of the validation suite by less than 0.01
    /// against 2e-4 s, at 2.5 times less cost.
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
            dt_s: 5e-4,
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

/// Two effects fitted jointly.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Combined {
    /// The two identifiers.
    pub effects: Vec<String>,
    /// Their parameters.
    pub params: BTreeMap<String, f64>,
    /// Fit runs: nominal gap, gap with both effects, shrink.
    pub fit: Shrink,
    /// Check runs: nominal gap, gap with both effects, shrink.
    pub check: Shrink,
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
    /// A second effect on top of the verdict's, when one was tested.
    pub second_effect: Option<Second>,
    /// The best pair of effects fitted jointly, when one was tested.
    pub combined: Option<Combined>,
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
    /// The recorded load with its noise reduced (the replay's input).
    pub load: Vec<f64>,
}

impl Run {
    /// Prepare a log.
    pub fn new(name: String, log: RunLog) -> Self {
        let m = measured(&log);
        let noise: [f64; 4] = std::array::from_fn(|c| noise_sigma(m[c]));
        let scale = std::array::from_fn(|c| noise[c].max(SCALE_FLOOR[c]));
        let labels = labels(&log);
        let load = filtered_load(&log);
        Self {
            name,
            log,
            noise,
            scale,
            labels,
            load,
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
            block_term(r, noise_part, s2)
        })
        .collect()
}

/// Excess power of one block whose mean residual is `r`: its expected noise
/// power `noise_part` removed, in units of the channel's scale squared `s2`
/// (a diverged replay counts as huge).
fn block_term(r: f64, noise_part: f64, s2: f64) -> f64 {
    if r.is_finite() {
        (r * r - noise_part) / s2
    } else {
        1e12
    }
}

/// A run's share of the pooled sum: its channels' mean excess times its length.
fn run_weight(excess: &[f64; 4], n: usize) -> f64 {
    excess.iter().sum::<f64>() / 4.0 * n as f64
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
        acc += run_weight(e, *n);
    }
    (acc / total as f64).sqrt()
}

/// The rig of a candidate; `None` when the effects cannot go on this plant.
fn rig_with(base: &Plant, effects: &Effects) -> Option<Rig> {
    Rig::new(base.clone(), *effects).ok()
}

/// Pooled gap of `runs` given their replays.
fn gap_of(runs: &[Run], sims: &[Replay]) -> f64 {
    let ex: Vec<[f64; 4]> = runs
        .iter()
        .zip(sims)
        .map(|(r, s)| channel_excess(r, s))
        .collect();
    let lens: Vec<usize> = runs.iter().map(|r| r.log.len()).collect();
    pooled(&ex, &lens)
}

/// Gap of `runs` under `effects` (infinite when the effects cannot go on the plant).
pub fn gap(runs: &[Run], base: &Plant, effects: &Effects, dt_s: f64) -> f64 {
    gap_bounded(runs, base, effects, dt_s, f64::INFINITY)
}

/// [`gap`] when it is at most `stop`; otherwise some value above `stop`:
/// the replays stop once the gap is certain to exceed it (a block's excess
/// is at least minus its expected noise power, so the blocks still to come
/// can lower a channel's sum by a known amount only). Not stopped, the
/// result is bit for bit that of the gap computed from full replays.
pub fn gap_bounded(runs: &[Run], base: &Plant, effects: &Effects, dt_s: f64, stop: f64) -> f64 {
    let Some(rig) = rig_with(base, effects) else {
        return f64::INFINITY;
    };
    let total: usize = runs.iter().map(|r| r.log.len()).sum();
    if total == 0 {
        return 0.0;
    }
    // The pooled gap is sqrt(acc / total): compare acc with stop^2 total.
    let limit = stop * stop * total as f64;
    let mut acc = 0.0;
    for run in runs {
        let n = run.log.len();
        let blocks = n.div_ceil(BLOCK);
        let meas = measured(&run.log);
        let s2: [f64; 4] = std::array::from_fn(|c| run.scale[c] * run.scale[c]);
        let noise_part: [f64; 4] =
            std::array::from_fn(|c| run.noise[c] * run.noise[c] / BLOCK as f64);
        let mut sums = [0.0f64; 4];
        let mut block = [0.0f64; 4];
        let mut in_block = 0usize;
        let mut done = 0usize;
        let mut bound = 0.0;
        replay_visit(&run.log, &run.load, &rig, dt_s, |k, v| {
            for c in 0..4 {
                block[c] += meas[c][k] - v[c];
            }
            in_block += 1;
            if in_block < BLOCK && k + 1 < n {
                return true;
            }
            for c in 0..4 {
                sums[c] += block_term(block[c] / in_block as f64, noise_part[c], s2[c]);
                block[c] = 0.0;
            }
            in_block = 0;
            done += 1;
            let left = (blocks - done) as f64;
            let low: [f64; 4] = std::array::from_fn(|c| {
                ((sums[c] - left * noise_part[c] / s2[c]) / blocks as f64).max(0.0)
            });
            bound = run_weight(&low, n);
            acc + bound <= limit
        });
        if done < blocks {
            return ((acc + bound) / total as f64)
                .sqrt()
                .max(stop * (1.0 + 1e-12));
        }
        let e: [f64; 4] = std::array::from_fn(|c| (sums[c] / blocks as f64).max(0.0));
        acc += run_weight(&e, n);
    }
    (acc / total as f64).sqrt()
}

/// The held-out runs confirm a model change that took their gap from
/// `before` to `after`: it shrinks by at least `min_shrink`, or it ends
/// within the noise (runs that show no gap beyond the noise do not excite
/// the effect: they can refute it, not confirm it).
fn confirms(before: f64, after: f64, min_shrink: f64) -> bool {
    Shrink::new(before, after).shrink >= min_shrink || after < NONE_GAP
}

/// Fit the parameters of `kinds` jointly (starting from their values in
/// `start`, else in `seeds`, else the typical ones; other effects of `start`
/// stay fixed) on `runs`.
fn fit_effects(
    runs: &[Run],
    base: &Plant,
    start: &Effects,
    seeds: &Effects,
    kinds: &[EffectKind],
    opts: &Options,
    max_evals: usize,
) -> (Effects, f64, usize) {
    let mut bounds = Vec::new();
    let mut x0 = Vec::new();
    for k in kinds {
        let now = start.get(*k).or_else(|| seeds.get(*k));
        for (i, p) in k.params().iter().enumerate() {
            bounds.push(Bound {
                lo: p.min,
                hi: p.max,
            });
            x0.push(
                now.as_ref()
                    .and_then(|v| v.get(i).copied())
                    .unwrap_or(p.typical),
            );
        }
    }
    let apply = |x: &[f64]| {
        let mut e = *start;
        let mut at = 0;
        for k in kinds {
            let n = k.params().len();
            e.set(*k, Some(&x[at..at + n]));
            at += n;
        }
        e
    };
    let mut objective = |x: &[f64], stop: f64| {
        let e = apply(x);
        if e.validate().is_err() {
            return f64::INFINITY;
        }
        gap_bounded(runs, base, &e, opts.dt_s, stop)
    };
    let r = minimize(&mut objective, &bounds, &x0, 9, max_evals);
    (apply(&r.x), r.value, r.evals)
}

/// Fit one effect on top of `fixed`.
fn fit_effect(
    runs: &[Run],
    base: &Plant,
    fixed: &Effects,
    seeds: &Effects,
    kind: EffectKind,
    opts: &Options,
) -> (Effects, f64, usize) {
    fit_effects(
        runs,
        base,
        fixed,
        seeds,
        &[kind],
        opts,
        grid_size(kind) + opts.max_evals,
    )
}

/// Points of the coarse grid of a one-effect fit: 9 for one parameter, 5 x 5
/// for two, 3 x 3 x 3 for three.
fn grid_size(kind: EffectKind) -> usize {
    match kind.params().len() {
        1 => 9,
        2 => 25,
        _ => 27,
    }
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
                .map(|r| replay_with_load(&r.log, &r.load, &rig, opts.dt_s))
                .collect(),
            None => Vec::new(),
        }
    };
    let nominal_fit = sims(&fit, &none);
    let nominal_check = sims(&check, &none);
    let before_fit = gap_of(&fit, &nominal_fit);
    let before_check = gap_of(&check, &nominal_check);
    let all: Vec<&Run> = fit.iter().chain(check.iter()).collect();
    let nominal: Vec<Replay> = nominal_fit.into_iter().chain(nominal_check).collect();
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
        combined: None,
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
    // Starting points where the gap is a narrow valley (see [`prefit`]).
    let mut seeds = Effects::NONE;
    if let Some(x) = prefit::motor_limit(&fit, base) {
        seeds.set(EffectKind::MotorLimit, Some(&x));
    }
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
            let (e, after_fit, evals) = fit_effect(&fit, base, &none, &seeds, k, opts);
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
    let single_ok =
        best.0.fit_shrink >= MIN_SHRINK && confirms(before_check, best.0.check_after, MIN_SHRINK);
    // A second effect where the best single one leaves a gap beyond the noise:
    // each of the two best singles with every other effect, the best pair
    // refitted jointly.
    let mut pair: Option<(EffectKind, EffectKind, Effects, f64, f64)> = None;
    if pooled_all >= NONE_GAP && opts.second_effect && best.0.fit_after >= NONE_GAP {
        let firsts: Vec<&(Candidate, Effects)> = cands.iter().take(2).collect();
        let tries: Vec<(EffectKind, EffectKind)> = firsts
            .iter()
            .map(|c| EffectKind::by_name(&c.0.effect).expect("known effect"))
            .flat_map(|k1| {
                EffectKind::ALL
                    .into_iter()
                    .filter(move |k| *k != k1)
                    .map(move |k2| (k1, k2))
            })
            .collect();
        let found: Vec<(EffectKind, EffectKind, Effects, f64)> = tries
            .par_iter()
            .map(|&(k1, k2)| {
                let start = cands
                    .iter()
                    .find(|c| c.0.effect == k1.name())
                    .expect("fitted")
                    .1;
                // Screening: the start point and the coarse grid only; the
                // best pair is then refined jointly.
                let budget = 1 + grid_size(k2) + k2.params().len();
                let (e, after, _) = fit_effects(&fit, base, &start, &seeds, &[k2], opts, budget);
                (k1, k2, e, after)
            })
            .collect();
        if let Some((k1, k2, e, _)) = found.into_iter().min_by(|a, b| a.3.total_cmp(&b.3)) {
            let (e, after_fit, _) =
                fit_effects(&fit, base, &e, &seeds, &[k1, k2], opts, 2 * opts.max_evals);
            let after_check = gap(&check, base, &e, opts.dt_s);
            pair = Some((k1, k2, e, after_fit, after_check));
        }
    }
    if pooled_all < NONE_GAP {
        diag.reason = format!(
            "the nominal model agrees with the runs within their noise (pooled gap {pooled_all:.2} < {NONE_GAP})"
        );
    } else {
        // The verdict's effect: the best single one, or the first of a pair
        // that explains the gap together when no single effect does.
        let pair_ok = pair.as_ref().is_some_and(|p| {
            Shrink::new(before_fit, p.3).shrink >= MIN_SHRINK
                && confirms(before_check, p.4, MIN_SHRINK)
        });
        let chosen = if single_ok {
            Some(best.clone())
        } else if pair_ok {
            let k1 = pair.as_ref().expect("pair").0;
            cands.iter().find(|c| c.0.effect == k1.name()).cloned()
        } else {
            None
        };
        match chosen {
            None => {
                diag.verdict = "unexplained".into();
                diag.reason = format!(
                    "gap {pooled_all:.2} beyond the noise; the best candidate ({}) shrinks it by {:.0} % on the fit runs and {:.0} % on the check runs (needed: {:.0} % on both, or the check runs brought or kept within the noise){}",
                    best.0.effect,
                    best.0.fit_shrink * 100.0,
                    best.0.check_shrink * 100.0,
                    MIN_SHRINK * 100.0,
                    match &pair {
                        Some(p) => format!(
                            ", and the best pair ({} + {}) by {:.0} % / {:.0} %",
                            p.0.name(),
                            p.1.name(),
                            Shrink::new(before_fit, p.3).shrink * 100.0,
                            Shrink::new(before_check, p.4).shrink * 100.0
                        ),
                        None => String::new(),
                    }
                );
            }
            Some(c) => {
                diag.verdict = c.0.effect.clone();
                diag.fit = Shrink::new(before_fit, c.0.fit_after);
                diag.check = Shrink::new(before_check, c.0.check_after);
                details.effects = c.1;
                let runner_up = cands.iter().find(|x| x.0.effect != c.0.effect);
                diag.reason = format!(
                    "{} shrinks the gap by {:.0} % on the fit runs and {:.0} % on the held-out check runs; the next candidate ({}) by {:.0} % / {:.0} %",
                    c.0.effect,
                    c.0.fit_shrink * 100.0,
                    c.0.check_shrink * 100.0,
                    runner_up.map(|x| x.0.effect.as_str()).unwrap_or("-"),
                    runner_up.map(|x| x.0.fit_shrink * 100.0).unwrap_or(0.0),
                    runner_up.map(|x| x.0.check_shrink * 100.0).unwrap_or(0.0)
                );
                if before_check < NONE_GAP {
                    diag.reason.push_str(&format!(
                        "; the check runs agree with the nominal model within the noise (gap {before_check:.2}) and stay so with the effect ({:.2}): they do not excite it, so they cannot confirm it, only not refute it",
                        c.0.check_after
                    ));
                }
            }
        }
        if let Some((k1, k2, e, after_fit, after_check)) = &pair {
            // The extra shrink the other effect of the pair gives on top of the verdict's.
            let (base_fit, base_check) = match cands.iter().find(|c| c.0.effect == diag.verdict) {
                Some(c) => (c.0.fit_after, c.0.check_after),
                None => (before_fit, before_check),
            };
            let other = if diag.verdict == k1.name() { *k2 } else { *k1 };
            let fit_extra = Shrink::new(base_fit, *after_fit).shrink;
            let check_extra = Shrink::new(base_check, *after_check).shrink;
            // Strict for the second effect: the check runs must shrink, not
            // merely stay within the noise (an extra effect fitted on top
            // overfits easily).
            let significant = fit_extra >= SECOND_SHRINK && check_extra >= SECOND_SHRINK;
            let mut params = params_map(e, *k1);
            params.extend(params_map(e, *k2));
            diag.second_effect = Some(Second {
                effect: other.name().to_string(),
                params: params_map(e, other),
                fit_extra_shrink: fit_extra,
                check_extra_shrink: check_extra,
                significant,
            });
            diag.combined = Some(Combined {
                effects: vec![k1.name().to_string(), k2.name().to_string()],
                params,
                fit: Shrink::new(before_fit, *after_fit),
                check: Shrink::new(before_check, *after_check),
            });
            if significant && diag.verdict != "unexplained" {
                details.effects = *e;
                diag.reason.push_str(&format!(
                    "; adding {} shrinks the remaining gap by a further {:.0} % / {:.0} %",
                    other.name(),
                    fit_extra * 100.0,
                    check_extra * 100.0
                ));
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gap::validation::{check_scenario, rig_log};
    use dca_core::controller::ControllerKind;

    #[test]
    fn bounded_gap_is_the_gap_or_above_the_stop() {
        let mut truth = Effects::NONE;
        truth.set(EffectKind::Leakage, Some(&[1e-13]));
        let runs = vec![Run::new(
            "c".into(),
            rig_log(check_scenario(), ControllerKind::Pid, &truth, 3),
        )];
        let base = Plant::nominal();
        let mut guess = Effects::NONE;
        guess.set(EffectKind::Leakage, Some(&[3e-14]));
        let sims: Vec<Replay> = runs
            .iter()
            .map(|r| replay_with_load(&r.log, &r.load, &rig_with(&base, &guess).unwrap(), 5e-4))
            .collect();
        let exact = gap_of(&runs, &sims);
        assert!(exact > 1.0, "{exact}");
        // Not stopped: bit for bit the gap of the full replays.
        assert_eq!(gap(&runs, &base, &guess, 5e-4).to_bits(), exact.to_bits());
        assert_eq!(
            gap_bounded(&runs, &base, &guess, 5e-4, exact * 1.001).to_bits(),
            exact.to_bits()
        );
        // Stopped: above the stop, not above the gap.
        for stop in [0.1, 0.5 * exact, 0.99 * exact] {
            let g = gap_bounded(&runs, &base, &guess, 5e-4, stop);
            assert!(
                g > stop && g <= exact * (1.0 + 1e-9),
                "{stop}: {g} vs {exact}"
            );
        }
    }
}
