//! Where the gap lies: the parts of the runs (channel, segment) that carry it,
//! and per run and channel the residual tests (whiteness, independence of
//! the drive command) and the residual's spectrum.

use super::diagnosis::{ChannelReport, Where};
use super::measure::{block_excess, channel_excess, BLOCK};
use super::replay::{measured, Replay, CHANNELS};
use super::run::Run;
use super::stats::{band_shares, independence, rms, whiteness};

/// The parts of the runs that carry the gap of the replays `sims`: per
/// channel, consecutive blocks grouped by segment label, the 12 largest
/// shares of a run's gap (at least 1 % each), largest first.
pub fn where_list(runs: &[&Run], sims: &[Replay]) -> Vec<Where> {
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

/// Residual tests and spectrum of every channel of every run against its replay.
pub fn channel_reports(runs: &[&Run], sims: &[Replay]) -> Vec<ChannelReport> {
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
                rms_residual: rms(&r),
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
