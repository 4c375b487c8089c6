//! The human report of a diagnosis: Markdown with plots.

use std::fmt::Write as _;
use std::path::Path;

use super::diagnosis::{Candidate, Details, Diagnosis};
use super::isolate::{Isolation, SAME_EQUATION_FACTOR, VIOLATED};
use super::measure::BLOCK;
use super::replay::{measured, Replay, CHANNELS};
use super::run::Run;
use crate::io::bars::{save_bars, Bars};
use crate::io::files::{self, PathError};
use crate::io::plot::{self, Panel, PlotError, Series};
use crate::model::effects::{
    self, CalChannel, FrictionMap, GasRelaxation, HysteresisSpectrum, LeakageMap, ScrewMap,
    SensorFilter, SensorMap, ServoEnvelope, ENVELOPE_SPEEDS_MPS, FILTER_DELAYS_S,
    FRICTION_SPEEDS_MPS, GAS_TAUS_S, LEAK_DP_PA, SCREW_FORCES_N, SPECTRUM_YIELDS_PA,
};

/// Why the report could not be written.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    /// The directory or the Markdown file.
    #[error(transparent)]
    File(#[from] PathError),
    /// A figure.
    #[error(transparent)]
    Plot(#[from] PlotError),
}

/// Display unit and scale of each channel (residual plots).
const UNITS: [(&str, f64); 4] = [("um", 1e6), ("um", 1e6), ("kPa", 1e-3), ("kPa", 1e-3)];

fn residual(run: &Run, sim: &Replay, c: usize) -> Vec<(f64, f64)> {
    let m = measured(&run.log)[c];
    let (_, k) = UNITS[c];
    // 10 ms block means, as the gap measures them.
    m.chunks(BLOCK)
        .zip(sim.ch[c].chunks(BLOCK))
        .enumerate()
        .map(|(i, (a, b))| {
            let r = a.iter().zip(b).map(|(x, y)| x - y).sum::<f64>() / a.len() as f64;
            (run.log.t_s[0] + (i * BLOCK) as f64 * run.log.dt_s(), r * k)
        })
        .collect()
}

fn residual_figure(
    path: &Path,
    runs: &[&Run],
    before: &[Replay],
    after: &[Replay],
    verdict: &str,
) -> Result<(), PlotError> {
    let mut panels = Vec::new();
    for (i, run) in runs.iter().enumerate() {
        for c in 0..4 {
            let (u, _) = UNITS[c];
            let mut p = Panel::new(
                format!("{}: {} residual (10 ms means)", run.name, CHANNELS[c]),
                "t [s]",
                format!("[{u}]"),
            )
            .with(Series::line("nominal model", residual(run, &before[i], c)));
            if let Some(a) = after.get(i) {
                p = p.with(Series::line(format!("with {verdict}"), residual(run, a, c)));
            }
            panels.push(p);
        }
    }
    plot::save(path, &panels, 1000, 220)
}

fn candidates_figure(path: &Path, d: &Diagnosis) -> Result<(), PlotError> {
    // Shrinks below -100 % (a model far worse than the nominal one) are
    // drawn at -100 %; the table gives the values.
    let shrinks = |pick: fn(&Candidate) -> f64| -> Vec<f64> {
        d.candidates
            .iter()
            .map(|c| pick(c).max(-1.0) * 100.0)
            .collect()
    };
    let bars = Bars {
        title: "candidate effects: gap shrink (fitted on the fit runs)".into(),
        y_label: "gap shrink [%]".into(),
        categories: d.candidates.iter().map(|c| c.effect.clone()).collect(),
        series: vec![
            ("fit runs".into(), shrinks(|c| c.fit_shrink)),
            ("check runs (held out)".into(), shrinks(|c| c.check_shrink)),
        ],
    };
    save_bars(path, &bars, 900, 380)
}

/// The learned servo envelope against speed, with the drive force the fit
/// runs show where the drive motors (m a + F from the encoder's speed and
/// acceleration over +-5 ms and the measured pressures): the envelope
/// should bound the cloud from above, and touch it where the drive was at
/// its limit.
fn envelope_figure(path: &Path, s: &ServoEnvelope, details: &Details) -> Result<(), PlotError> {
    let curve: Vec<(f64, f64)> = (0..=120)
        .map(|i| {
            let v = i as f64 * 1e-3;
            (v * 1e3, s.available_n(v))
        })
        .collect();
    let mut points = Vec::new();
    for run in &details.fit {
        let log = &run.log;
        let dt = log.dt_s();
        let h = ((5e-3 / dt).round() as usize).max(1);
        let mut k = h;
        while k + h < log.len() {
            let v = (log.xi_m[k + h] - log.xi_m[k - h]) / (2.0 * h as f64 * dt);
            let a =
                (log.xi_m[k + h] - 2.0 * log.xi_m[k] + log.xi_m[k - h]) / (h as f64 * dt).powi(2);
            let f = s.mass_eq_kg * a + details.base.piston_force_n(log.p1_pa[k], log.p2_pa[k]);
            if f * v > 0.0 && v.abs() > 1e-3 {
                points.push((v.abs() * 1e3, f.abs()));
            }
            k += h;
        }
    }
    let panel = Panel::new(
        format!(
            "motor_limit, general family: available drive force over speed (reflected mass {:.0} kg{})",
            s.mass_eq_kg,
            s.accel_max_mps2
                .map_or(String::new(), |a| format!(", ramp {a:.2} m/s^2"))
        ),
        "speed of the power piston [mm/s]",
        "drive force [N]",
    )
    .with(Series::line("learned envelope A(v)", curve))
    .with(Series::points("fit runs while motoring: m a + F", points));
    plot::save(path, &[panel], 900, 420)
}

/// The wall's hysteretic volume of one line (mm^3) over its pressure (MPa)
/// on a cycle 0 -> 4 MPa -> 1 MPa -> 3 MPa -> 0, 2 kPa per point: the
/// spectrum's elements driven by that pressure, their engaged compliances
/// integrated.
fn spectrum_loop(h: &HysteresisSpectrum) -> Vec<(f64, f64)> {
    let mut z = [0.0; SPECTRUM_YIELDS_PA.len()];
    let (mut p, mut v) = (0.0_f64, 0.0_f64);
    let mut loop_pts = vec![(0.0, 0.0)];
    let dp_step = 2e3;
    for target in [4e6, 1e6, 3e6, 0.0] {
        while (target - p).abs() > 0.5 * dp_step {
            let dp = dp_step.copysign(target - p);
            for (i, zi) in z.iter_mut().enumerate() {
                v += h.compliance_m3pp(i, *zi, dp) * dp;
                *zi += effects::hysteresis_rate(&h.element(i), *zi, dp);
            }
            p += dp;
            loop_pts.push((p * 1e-6, v * 1e9));
        }
    }
    loop_pts
}

/// The learned hose-wall hysteresis ([`spectrum_loop`]), so that the loop's
/// width and shape can be read.
fn spectrum_figure(path: &Path, h: &HysteresisSpectrum) -> Result<(), PlotError> {
    let panel = Panel::new(
        "hose_hysteresis, general family: the wall's hysteretic volume of one line over a pressure cycle",
        "line pressure [MPa]",
        "hysteretic wall volume [mm^3]",
    )
    .with(Series::line("0 -> 4 -> 1 -> 3 -> 0 MPa", spectrum_loop(h)));
    plot::save(path, &[panel], 900, 420)
}

/// Display units of a channel's values and of its small deviations, with
/// their scales from SI: mm and um for the positions, MPa and kPa for the
/// pressures.
fn display_units(ch: CalChannel) -> ((&'static str, f64), (&'static str, f64)) {
    match ch {
        CalChannel::Xo | CalChannel::Xi => (("mm", 1e3), ("um", 1e6)),
        CalChannel::P1 | CalChannel::P2 => (("MPa", 1e-6), ("kPa", 1e-3)),
        CalChannel::Ft => (("N", 1.0), ("N", 1.0)),
    }
}

/// The learned sensor filter: its step response (the share of a step the
/// channel reports after each delay) and its impulse weights.
fn filter_figure(path: &Path, f: &SensorFilter) -> Result<(), PlotError> {
    let w = f.normalised();
    let mut acc = 0.0;
    let mut step = vec![(0.0, 0.0)];
    for (d, wi) in FILTER_DELAYS_S.iter().zip(w) {
        step.push((d * 1e3, acc));
        acc += wi;
        step.push((d * 1e3, acc));
    }
    step.push((FILTER_DELAYS_S[FILTER_DELAYS_S.len() - 1] * 1e3 + 4.0, acc));
    let taps = FILTER_DELAYS_S
        .iter()
        .zip(w)
        .map(|(d, wi)| (d * 1e3, wi))
        .collect();
    let panel = Panel::new(
        format!(
            "sensor_delay, general family: the learned lag of {} (mean delay {:.2} ms)",
            f.channel.name(),
            f.mean_delay_s() * 1e3
        ),
        "time after a step of the true value [ms]",
        "share of the step reported",
    )
    .with(Series::line("step response", step))
    .with(Series::points("tap weights", taps));
    plot::save(path, &[panel], 900, 420)
}

/// The learned sensor map as its deviation from the identity over the true
/// value, with the fit runs' recorded-minus-replayed points behind it.
fn map_figure(path: &Path, m: &SensorMap, details: &Details) -> Result<(), PlotError> {
    let c = m.channel.index();
    let ((vu, vk), (du, dk)) = display_units(m.channel);
    let (lo, hi) = (m.knots_si[0], m.knots_si[m.knots_si.len() - 1]);
    let curve = (0..=200)
        .map(|i| {
            let v = lo + (hi - lo) * i as f64 / 200.0;
            (v * vk, (m.map(v) - v) * dk)
        })
        .collect();
    let mut points = Vec::new();
    // The force sensor's reading is the replay's input: no replayed values
    // to set it against.
    let replayed = if m.channel == CalChannel::Ft {
        &[][..]
    } else {
        &details.before[..]
    };
    for (run, sim) in details.fit.iter().zip(replayed) {
        let y = measured(&run.log)[c];
        for (k, v) in sim.ch[c].iter().enumerate().step_by(BLOCK) {
            if v.is_finite() && y[k].is_finite() {
                points.push((v * vk, (y[k] - v) * dk));
            }
        }
    }
    let panel = Panel::new(
        format!(
            "sensor_calibration, general family: the learned map of {}",
            m.channel.name()
        ),
        format!("true value [{vu}]"),
        format!("recorded minus true [{du}]"),
    )
    .with(Series::points(
        "fit runs: recorded minus the nominal replay",
        points,
    ))
    .with(Series::line("learned map minus identity", curve));
    plot::save(path, &[panel], 900, 420)
}

/// The learned seal friction: its magnitude over speed with P1 + P2 at 0,
/// 2 and 5 MPa.
fn friction_figure(path: &Path, f: &FrictionMap) -> Result<(), PlotError> {
    let mut panel = Panel::new(
        "friction, general family: the seals' learned friction over the piston speed",
        "speed of the actuating piston [mm/s]",
        "friction force [N]",
    );
    for p_mpa in [0.0, 2.0, 5.0] {
        let curve = (0..=400)
            .map(|i| {
                let v = 0.12 * i as f64 / 400.0;
                (v * 1e3, f.magnitude_n(v, p_mpa * 1e6, 0.0))
            })
            .collect();
        panel = panel.with(Series::line(format!("P1 + P2 = {p_mpa} MPa"), curve));
    }
    plot::save(path, &[panel], 900, 420)
}

/// The learned internal leakage: the flow over the pressure difference
/// with the mean line pressure at 1 and 3 MPa.
fn leakage_figure(path: &Path, l: &LeakageMap) -> Result<(), PlotError> {
    let mut panel = Panel::new(
        "leakage, general family: the seals' learned leakage over the pressure difference",
        "P1 - P2 [MPa]",
        "leakage flow from line 1 to line 2 [cm^3/s]",
    );
    for mean_mpa in [1.0, 3.0] {
        let curve = (0..=200)
            .map(|i| {
                let dp = -5e6 + 10e6 * i as f64 / 200.0;
                let p2 = mean_mpa * 1e6 - 0.5 * dp;
                (dp * 1e-6, l.flow(p2 + dp, p2) * 1e6)
            })
            .collect();
        panel = panel.with(Series::line(
            format!("mean line pressure {mean_mpa} MPa"),
            curve,
        ));
    }
    plot::save(path, &[panel], 900, 420)
}

/// The learned gas relaxation as the gas's effective polytropic index over
/// the time after a step compression (on a log time axis, 10 ms to 100 s),
/// beside the nominal index and the isothermal one.
fn gas_figure(path: &Path, g: &GasRelaxation, n_poly: f64) -> Result<(), PlotError> {
    let lg = |i: usize| -2.0 + 4.0 * i as f64 / 200.0;
    let curve = (0..=200)
        .map(|i| (lg(i), g.index_after(n_poly, 10f64.powf(lg(i)))))
        .collect();
    let flat = |v: f64| vec![(lg(0), v), (lg(200), v)];
    let panel = Panel::new(
        "accumulator_thermal, general family: the gas's index after a step compression",
        "time after the step, log10(t / 1 s)",
        "effective polytropic index",
    )
    .with(Series::line("learned", curve))
    .with(Series::dashed(
        format!("nominal (adiabatic, {n_poly})"),
        flat(n_poly),
    ))
    .with(Series::dashed("isothermal (1)", flat(1.0)));
    plot::save(path, &[panel], 900, 420)
}

/// The learned coupling: the power piston's deflection behind the motor
/// over the hydraulic force on it, -2 kN to 2 kN.
fn screw_figure(path: &Path, m: &ScrewMap) -> Result<(), PlotError> {
    let curve = (0..=400)
        .map(|i| {
            let f = -2000.0 + 4000.0 * i as f64 / 400.0;
            (f, m.offset_m(f) * 1e6)
        })
        .collect();
    let panel = Panel::new(
        "backlash, general family: the power piston's deflection behind the motor",
        "hydraulic force on the power piston [N]",
        "deflection behind the encoder [um]",
    )
    .with(Series::line("learned", curve));
    plot::save(path, &[panel], 900, 420)
}

/// `s` with its first letter in upper case (a sentence's start).
fn capitalised(s: &str) -> String {
    let mut c = s.chars();
    c.next()
        .map(|f| f.to_uppercase().chain(c).collect())
        .unwrap_or_default()
}

/// Write `report.md` and its figures into `dir`.
pub fn write(dir: &Path, d: &Diagnosis, details: &Details) -> Result<(), ReportError> {
    files::create_dir_all(dir)?;
    let runs: Vec<&Run> = details.fit.iter().chain(details.check.iter()).collect();
    residual_figure(
        &dir.join("residuals.png"),
        &runs,
        &details.before,
        &details.after,
        d.verdict.name(),
    )?;
    candidates_figure(&dir.join("candidates.png"), d)?;
    let mut md = String::new();
    header(&mut md, d, details);
    isolation_section(&mut md, &d.isolation);
    effect_sections(dir, &mut md, details)?;
    parameters_section(&mut md, d);
    candidates_section(&mut md, d);
    where_section(&mut md, d);
    let _ = writeln!(md, "Diagnosis took {:.1} s.", d.elapsed_s);
    let path = dir.join("report.md");
    Ok(files::write(&path, md)?)
}

/// The verdict, its gaps and the form that held.
fn header(md: &mut String, d: &Diagnosis, details: &Details) {
    let _ = writeln!(md, "# Sim-to-real gap diagnosis\n");
    let _ = writeln!(
        md,
        "**Verdict: `{}`**. {}\n",
        d.verdict,
        capitalised(&d.reason)
    );
    let _ = writeln!(md, "Gap: {}.\n", d.gap_metric);
    let _ = writeln!(md, "| runs | before | after | shrink |\n|---|---|---|---|");
    let _ = writeln!(
        md,
        "| fit ({}) | {:.2} | {:.2} | {:.0} % |",
        details.fit.len(),
        d.fit.before,
        d.fit.after,
        d.fit.shrink * 100.0
    );
    let _ = writeln!(
        md,
        "| check, held out ({}) | {:.2} | {:.2} | {:.0} % |\n",
        details.check.len(),
        d.check.before,
        d.check.after,
        d.check.shrink * 100.0
    );
    if let Some(s) = &d.second_effect {
        let _ = writeln!(
            md,
            "Second effect on top: `{}` shrinks the remaining gap by {:.0} % (fit) and {:.0} % (check): {}.\n",
            s.effect,
            s.fit_extra_shrink * 100.0,
            s.check_extra_shrink * 100.0,
            if s.significant { "significant" } else { "not significant" }
        );
    }
    if let (Some(form), Some(sub)) = (&d.form, &d.subsystem) {
        let _ = writeln!(md, "Form that held: {form} (subsystem: {sub}).\n");
    }
    let named = d
        .candidates
        .iter()
        .find(|c| c.effect == d.verdict.name())
        .and_then(|c| c.named.as_ref());
    if let Some(n) = named {
        let params: Vec<String> = n
            .params
            .iter()
            .map(|(k, v)| format!("{k} = {v:.4e}"))
            .collect();
        let _ = writeln!(
            md,
            "The named form, which the general family refined, fitted {} (fit shrink {:.0} %, \
             check shrink {:.0} %).\n",
            params.join(", "),
            100.0 * n.fit_shrink,
            100.0 * n.check_shrink
        );
    }
}

/// Where first: the residuals of the model's equations, the closures that
/// explain them, and the equation the verdict stands on.
fn isolation_section(md: &mut String, iso: &Isolation) {
    let _ = writeln!(
        md,
        "## Where first: which equation the runs violate\n\n\
         Each residual checks some of the model's equations on the measurements alone; its \
         excess is the mean over 10 ms blocks of the squared block mean in units of its noise, \
         less one (0 within the noise; beyond {VIOLATED} it is violated).\n\n\
         | residual | checks | fit runs | check runs | violated |\n|---|---|---|---|---|"
    );
    for r in &iso.residuals {
        let _ = writeln!(
            md,
            "| {} | {} | {:.1} | {:.1} | {} |",
            r.residual,
            r.checks,
            r.fit,
            r.check,
            if r.violated { "**yes**" } else { "no" }
        );
    }
    let _ = writeln!(
        md,
        "\nA closure adds a term of any shape over one equation's own variables to that \
         equation alone, fitted on the fit runs; it is judged by what it leaves of the \
         residuals' excess (per block, fit runs penalised by twice its weights, check runs as \
         they are). The best closures:\n\n\
         | equation | depends on | names | leaves (fit) | leaves (check) | leaves (all) | explains of the check runs |\n|---|---|---|---|---|---|---|"
    );
    for c in iso.closures.iter().take(8) {
        let _ = writeln!(
            md,
            "| {} | {} | `{}` | {:.2} | {:.2} | {:.2} | {:.0} % |",
            c.closure.site.name(),
            c.closure.dep.name(),
            c.names,
            c.fit_left,
            c.check_left,
            c.left,
            100.0 * c.check_explained
        );
    }
    let _ = writeln!(
        md,
        "\n**Violated: {}, depending on {}** (the table of docs/gap.md names this `{}`). \
         Effects the verdict may name (closures that leave about as much as the best, or \
         of the same equation within {SAME_EQUATION_FACTOR} times what it leaves): {}.\n",
        iso.equation,
        iso.dependence,
        iso.names,
        iso.may_name
            .iter()
            .map(|n| format!("`{n}`"))
            .collect::<Vec<_>>()
            .join(", ")
    );
}

/// Each learned general family of the verdict's effects: its table and figure.
fn effect_sections(dir: &Path, md: &mut String, details: &Details) -> Result<(), ReportError> {
    if let Some(h) = &details.effects.hose_spectrum {
        hose_spectrum_section(dir, md, h)?;
    }
    if let Some(s) = &details.effects.servo_envelope {
        servo_envelope_section(dir, md, s, details)?;
    }
    if let Some(f) = &details.effects.friction_map {
        friction_map_section(dir, md, f)?;
    }
    if let Some(l) = &details.effects.leakage_map {
        leakage_map_section(dir, md, l)?;
    }
    if let Some(m) = &details.effects.screw_map {
        screw_map_section(dir, md, m)?;
    }
    if let Some(g) = &details.effects.gas_relaxation {
        gas_relaxation_section(dir, md, g, details)?;
    }
    if let Some(f) = &details.effects.sensor_filter {
        sensor_filter_section(dir, md, f)?;
    }
    if let Some(m) = &details.effects.sensor_map {
        sensor_map_section(dir, md, m, details)?;
    }
    Ok(())
}

/// The hose wall's learned hysteresis: its compliances over the yields.
fn hose_spectrum_section(
    dir: &Path,
    md: &mut String,
    h: &HysteresisSpectrum,
) -> Result<(), ReportError> {
    spectrum_figure(&dir.join("hose_spectrum.png"), h)?;
    let _ = writeln!(
        md,
        "## The hose wall's learned hysteresis\n\n\
         | element yield [kPa] | {} |\n|---|{}\n| compliance when engaged (play) [m^3/Pa] | {} |\n\
         | compliance while not engaged (stop) [m^3/Pa] | {} |\n\n\
         ![hose hysteresis](hose_spectrum.png)\n",
        SPECTRUM_YIELDS_PA
            .map(|y| format!("{:.0}", y * 1e-3))
            .join(" | "),
        "---|".repeat(SPECTRUM_YIELDS_PA.len()),
        h.c_m3pp.map(|c| format!("{c:.2e}")).join(" | "),
        h.stop_c_m3pp.map(|c| format!("{c:.2e}")).join(" | "),
    );
    Ok(())
}

/// The servo's learned force envelope over speed.
fn servo_envelope_section(
    dir: &Path,
    md: &mut String,
    s: &ServoEnvelope,
    details: &Details,
) -> Result<(), ReportError> {
    envelope_figure(&dir.join("servo_envelope.png"), s, details)?;
    let _ = writeln!(
        md,
        "## The servo's learned force envelope\n\n\
         | speed [mm/s] | {} |\n|---|{}\n| available force [N] | {} |\n\n\
         Reflected mass {:.1} kg.{} Knots that the fit runs never press stay at the force of \
         the knot below them.\n\n![servo envelope](servo_envelope.png)\n",
        ENVELOPE_SPEEDS_MPS
            .map(|v| format!("{:.0}", v * 1e3))
            .join(" | "),
        "---|".repeat(ENVELOPE_SPEEDS_MPS.len()),
        s.force_n.map(|f| format!("{f:.0}")).join(" | "),
        s.mass_eq_kg,
        s.accel_max_mps2.map_or(String::new(), |a| format!(
            " The drive ramps its speed target at {a:.2} m/s^2 at most, whatever the load."
        ))
    );
    Ok(())
}

/// The seals' learned friction over speed.
fn friction_map_section(dir: &Path, md: &mut String, f: &FrictionMap) -> Result<(), ReportError> {
    friction_figure(&dir.join("friction_map.png"), f)?;
    let _ = writeln!(
        md,
        "## The seals' learned friction\n\n\
         | speed [mm/s] | {} |\n|---|{}\n| friction at P1 + P2 = 0 [N] | {} |\n\n\
         Plus {:.1} N per MPa of P1 + P2. Flat beyond the last knot.\n\n\
         ![friction map](friction_map.png)\n",
        FRICTION_SPEEDS_MPS
            .map(|v| format!("{:.1}", v * 1e3))
            .join(" | "),
        "---|".repeat(FRICTION_SPEEDS_MPS.len()),
        f.force_n.map(|x| format!("{x:.1}")).join(" | "),
        f.n_per_mpa
    );
    Ok(())
}

/// The seals' learned leakage over the pressure difference.
fn leakage_map_section(dir: &Path, md: &mut String, l: &LeakageMap) -> Result<(), ReportError> {
    leakage_figure(&dir.join("leakage_map.png"), l)?;
    let _ = writeln!(
        md,
        "## The seals' learned leakage\n\n\
         | abs(P1 - P2) [MPa] | {} |\n|---|{}\n| flow [cm^3/s] | {} |\n\n\
         Plus {:.3e} m^3/(s Pa) times dP per MPa of mean line pressure. Linear beyond \
         the last knot.\n\n![leakage map](leakage_map.png)\n",
        LEAK_DP_PA[1..]
            .iter()
            .map(|p| format!("{:.2}", p * 1e-6))
            .collect::<Vec<_>>()
            .join(" | "),
        "---|".repeat(LEAK_DP_PA.len() - 1),
        l.q_m3ps.map(|q| format!("{:.3}", q * 1e6)).join(" | "),
        l.g_m3pspa
    );
    Ok(())
}

/// The coupling's learned deflection over force.
fn screw_map_section(dir: &Path, md: &mut String, m: &ScrewMap) -> Result<(), ReportError> {
    screw_figure(&dir.join("screw_map.png"), m)?;
    let _ = writeln!(
        md,
        "## The coupling's learned deflection\n\n\
         | force on the power piston [N] | {} |\n|---|{}\n| deflection [um] | {} |\n\n\
         Odd in the force; linear beyond the last knot. The step from 0 N to the first knot \
         is the play crossed where the force turns.\n\n![screw map](screw_map.png)\n",
        SCREW_FORCES_N[1..]
            .iter()
            .map(|f| format!("{f:.0}"))
            .collect::<Vec<_>>()
            .join(" | "),
        "---|".repeat(SCREW_FORCES_N.len() - 1),
        m.deflection_m
            .map(|d| format!("{:.1}", d * 1e6))
            .join(" | "),
    );
    Ok(())
}

/// The accumulator gas's learned relaxation over its time constants.
fn gas_relaxation_section(
    dir: &Path,
    md: &mut String,
    g: &GasRelaxation,
    details: &Details,
) -> Result<(), ReportError> {
    let n_poly = details.base.params().n_poly;
    gas_figure(&dir.join("gas_relaxation.png"), g, n_poly)?;
    let _ = writeln!(
        md,
        "## The accumulator gas's learned relaxation\n\n\
         | time constant [s] | {} |\n|---|{}\n| weight | {} |\n\n\
         A step compression meets the index {n_poly}; after 1 s it is {:.3}, after 10 s \
         {:.3}, at length {:.3}.\n\n![gas relaxation](gas_relaxation.png)\n",
        GAS_TAUS_S.map(|t| format!("{t}")).join(" | "),
        "---|".repeat(GAS_TAUS_S.len()),
        g.weights.map(|w| format!("{w:.3}")).join(" | "),
        g.index_after(n_poly, 1.0),
        g.index_after(n_poly, 10.0),
        g.index_after(n_poly, f64::INFINITY),
    );
    Ok(())
}

/// A sensor's learned lag: its weights over the delays.
fn sensor_filter_section(dir: &Path, md: &mut String, f: &SensorFilter) -> Result<(), ReportError> {
    filter_figure(&dir.join("sensor_filter.png"), f)?;
    let _ = writeln!(
        md,
        "## The learned lag of `{}`\n\n\
         | delay [ms] | {} |\n|---|{}\n| weight | {} |\n\n\
         Mean delay {:.2} ms.\n\n![sensor filter](sensor_filter.png)\n",
        f.channel.name(),
        FILTER_DELAYS_S
            .map(|d| format!("{:.0}", d * 1e3))
            .join(" | "),
        "---|".repeat(FILTER_DELAYS_S.len()),
        f.normalised().map(|w| format!("{w:.3}")).join(" | "),
        f.mean_delay_s() * 1e3
    );
    Ok(())
}

/// A sensor's learned static map.
fn sensor_map_section(
    dir: &Path,
    md: &mut String,
    m: &SensorMap,
    details: &Details,
) -> Result<(), ReportError> {
    map_figure(&dir.join("sensor_map.png"), m, details)?;
    let ((vu, vk), (du, dk)) = display_units(m.channel);
    let _ = writeln!(
        md,
        "## The learned map of `{}`\n\n\
         | true value [{vu}] | {} |\n|---|{}\n| recorded minus true [{du}] | {} |\n\n\
         Linear beyond the end knots.\n\n![sensor map](sensor_map.png)\n",
        m.channel.name(),
        m.knots_si.map(|k| format!("{:.3}", k * vk)).join(" | "),
        "---|".repeat(m.knots_si.len()),
        m.knots_si
            .iter()
            .zip(m.readings_si)
            .map(|(k, r)| format!("{:.1}", (r - k) * dk))
            .collect::<Vec<_>>()
            .join(" | "),
    );
    Ok(())
}

/// The grey-box re-estimate of the nominal parameters.
fn parameters_section(md: &mut String, d: &Diagnosis) {
    if !d.parameters.is_empty() {
        let _ = writeln!(
            md,
            "## Re-estimated parameters (`parameters`, grey box, fit runs)\n\n\
             95 % intervals from s^2 (J^T J)^-1 at the estimate, J the Jacobian of the 10 ms \
             block-mean residuals in ln(value), s^2 their mean square, inflated for their lag-1 \
             autocorrelation.\n\n\
             | parameter | nominal | re-estimate | 95 % interval | ratio | at bound |\n|---|---|---|---|---|---|"
        );
        for e in &d.parameters {
            let _ = writeln!(
                md,
                "| `{}` | {:.4e} | {:.4e} | {:.4e} .. {:.4e} | {:.3} | {} |",
                e.key,
                e.nominal,
                e.value,
                e.ci95[0],
                e.ci95[1],
                e.ratio,
                if e.at_bound { "yes" } else { "no" }
            );
        }
        let _ = writeln!(md);
    }
}

/// The candidates fitted on the fit runs.
fn candidates_section(md: &mut String, d: &Diagnosis) {
    let _ = writeln!(md, "## Candidates (fitted on the fit runs only)\n");
    let _ = writeln!(
        md,
        "| rank | effect | form | fitted parameters | fit shrink | check shrink |\n|---|---|---|---|---|---|"
    );
    for (i, c) in d.candidates.iter().enumerate() {
        let params: Vec<String> = c
            .params
            .iter()
            .map(|(k, v)| format!("{k} = {v:.3e}"))
            .collect();
        let _ = writeln!(
            md,
            "| {} | `{}` | {} | {} | {:.0} % | {:.0} % |",
            i + 1,
            c.effect,
            c.form,
            params.join(", "),
            c.fit_shrink * 100.0,
            c.check_shrink * 100.0
        );
    }
    let _ = writeln!(md, "\n![ranking](candidates.png)\n");
}

/// Where the gap lies and the residual tests, per run and channel.
fn where_section(md: &mut String, d: &Diagnosis) {
    let _ = writeln!(md, "## Where the gap lies (nominal model)\n");
    let _ = writeln!(md, "| run | channel | from [s] | to [s] | segment | share of the run's gap |\n|---|---|---|---|---|---|");
    for w in &d.where_ {
        let _ = writeln!(
            md,
            "| {} | {} | {:.2} | {:.2} | {} | {:.0} % |",
            w.run,
            w.channel,
            w.t0_s,
            w.t1_s,
            w.label,
            w.share * 100.0
        );
    }
    let _ = writeln!(md, "\n## Residual tests (nominal model, 99 %)\n");
    let _ = writeln!(
        md,
        "| run | channel | gap | noise | RMS residual | white | independent of the command | band shares {} |\n|---|---|---|---|---|---|---|---|",
        d.bands_hz.iter().map(|b| format!("{}-{} Hz", b[0], b[1])).collect::<Vec<_>>().join(" / ")
    );
    for c in &d.channels {
        let _ = writeln!(
            md,
            "| {} | {} | {:.2} | {:.3e} | {:.3e} | {} | {} | {} |",
            c.run,
            c.channel,
            c.gap,
            c.noise,
            c.rms_residual,
            if c.white { "yes" } else { "no" },
            if c.independent_of_input { "yes" } else { "no" },
            c.band_shares
                .iter()
                .map(|x| format!("{:.0} %", x * 100.0))
                .collect::<Vec<_>>()
                .join(" / ")
        );
    }
    let _ = writeln!(
        md,
        "\n## Residuals before and after\n\n![residuals](residuals.png)\n"
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The coupling's learned deflection is drawn (a PNG with content); a
    /// map whose deflection falls with force is not a valid one.
    #[test]
    fn screw_map_figure_is_written() {
        let dir = std::env::temp_dir().join(format!("dca-screw-{}", std::process::id()));
        files::create_dir_all(&dir).unwrap();
        let path = dir.join("screw_map.png");
        let m = ScrewMap {
            deflection_m: [24e-6, 31.9e-6, 34.3e-6, 39.0e-6, 50e-6, 71.6e-6],
        };
        assert!(m.is_valid());
        screw_figure(&path, &m).unwrap();
        assert!(std::fs::metadata(&path).unwrap().len() > 1000);
        let falling = ScrewMap {
            deflection_m: [24e-6, 20e-6, 34.3e-6, 39.0e-6, 50e-6, 71.6e-6],
        };
        assert!(!falling.is_valid());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// The learned loop is a hysteresis loop: on the way down the wall holds
    /// more volume than on the way up at the same pressure, more so with a
    /// larger yield; without compliance it is flat.
    #[test]
    fn spectrum_loop_opens_with_the_yield() {
        let width_at_2mpa = |c: [f64; 5]| {
            let pts = spectrum_loop(&HysteresisSpectrum::plays(c));
            let near = |from: usize, to: usize| {
                pts[from..to]
                    .iter()
                    .min_by(|a, b| (a.0 - 2.0).abs().total_cmp(&(b.0 - 2.0).abs()))
                    .expect("points")
                    .1
            };
            // Up to 4 MPa: the first 2 000 points; then down to 1 MPa.
            near(2000, 3500) - near(0, 2000)
        };
        assert_eq!(width_at_2mpa([0.0; 5]), 0.0);
        let narrow = width_at_2mpa([1e-13, 0.0, 0.0, 0.0, 0.0]);
        let wide = width_at_2mpa([0.0, 0.0, 0.0, 1e-13, 0.0]);
        assert!(narrow > 0.0 && wide > narrow, "{narrow} {wide}");
    }
}
