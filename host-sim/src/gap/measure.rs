//! The gap: how far a model's replays of the runs lie from the measurements,
//! beyond the noise (see [`GAP_METRIC`]), per run and pooled over runs, and
//! its shrink when effects are added.

use super::replay::{measured, replay_visit, replay_with_load, Replay};
use super::run::Run;
use crate::model::effects::Effects;
use crate::model::plant::Plant;
use crate::model::rig::Rig;
use serde::Serialize;

/// One sentence for the report: what the gap measures.
pub const GAP_METRIC: &str = "RMS over the channels xo_m, xi_m, p1_pa, p2_pa of the 10 ms block mean of \
the residual (measured minus the nominal model replayed on the recorded drive command and load), its \
expected white-noise part removed, each in units of that channel's noise level estimated from the \
log (dimensionless; 0 = agreement within the noise)";

/// The gap clean runs show (0.3 to 0.6 on realistic sensors): a model that
/// leaves less has nothing left to explain (used by [`super::policy`] and
/// [`super::grey_box`]).
pub const CLEAN_GAP: f64 = 0.5;
/// Samples per block of the block-mean residual.
pub const BLOCK: usize = 10;
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
    /// Before and after; shrink = 1 - after / before (0 when before is 0).
    pub fn new(before: f64, after: f64) -> Self {
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

/// Block-mean normalised residuals of one channel and their noise-free
/// excess power per block.
pub fn block_excess(run: &Run, sim: &Replay, c: usize) -> Vec<f64> {
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
pub fn channel_excess(run: &Run, sim: &Replay) -> [f64; 4] {
    std::array::from_fn(|c| {
        let b = block_excess(run, sim, c);
        (b.iter().sum::<f64>() / b.len().max(1) as f64).max(0.0)
    })
}

/// Pooled gap of several runs from their per-channel excess powers.
pub fn pooled(excess: &[[f64; 4]], lens: &[usize]) -> f64 {
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
pub fn rig_with(base: &Plant, effects: &Effects) -> Option<Rig> {
    Rig::new(base.clone(), *effects).ok()
}

/// Replays of `runs` on `base` with `effects` (none when the effects cannot
/// go on the plant).
pub fn replays(runs: &[Run], base: &Plant, effects: &Effects, dt_s: f64) -> Vec<Replay> {
    match rig_with(base, effects) {
        Some(rig) => runs
            .iter()
            .map(|r| replay_with_load(&r.log, &r.load, &rig, dt_s))
            .collect(),
        None => Vec::new(),
    }
}

/// Pooled gap of `runs` given their replays.
pub fn gap_of(runs: &[Run], sims: &[Replay]) -> f64 {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gap::replay::replay_with_load;
    use crate::gap::validation::{check_scenario, rig_log};
    use crate::model::effects::EffectKind;
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
