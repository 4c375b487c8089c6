//! Scenarios of docs/model.md section 7.
//!
//! A scenario is data: a name, a duration, a command (a position reference for the
//! closed loop, or an open-loop servo velocity command) and a load, each a [`Signal`] of
//! time. Signals are built from a few primitives ([`Signal::Constant`], [`Signal::Sine`],
//! [`Signal::Cosine`], [`Signal::Ramp`]) and [`Piecewise`] switching, so custom
//! scenarios (e.g. read from TOML) are built from the same parts as the nominal ones.
//!
//! Time is sampled as t_k = k dt ([`tick_time_s`]); switching instants are evaluated
//! with `t_k < threshold` exactly as section 7 says.

use core::f64::consts::PI;
use core::fmt;

/// Names of the nominal scenarios of docs/model.md section 7, in table order.
pub const NOMINAL_NAMES: [&str; 5] = ["step", "sine", "stepload", "sineload", "openloop"];

/// Time of tick `k` at step `dt_s`, t_k = (k as f64) dt, s (docs/model.md section 7).
#[inline]
pub fn tick_time_s(k: u64, dt_s: f64) -> f64 {
    k as f64 * dt_s
}

/// A scalar signal of time, in the unit of whatever it drives (m, N or m/s).
#[derive(Clone, Debug, PartialEq)]
pub enum Signal {
    /// A constant value.
    Constant(f64),
    /// `bias + amplitude sin(omega (t - t0))`.
    Sine {
        /// Offset added to the sine.
        bias: f64,
        /// Amplitude of the sine.
        amplitude: f64,
        /// Angular frequency, rad/s.
        omega_radps: f64,
        /// Time origin of the phase, s.
        t0_s: f64,
    },
    /// `bias + amplitude cos(omega (t - t0))`.
    Cosine {
        /// Offset added to the cosine.
        bias: f64,
        /// Amplitude of the cosine.
        amplitude: f64,
        /// Angular frequency, rad/s.
        omega_radps: f64,
        /// Time origin of the phase, s.
        t0_s: f64,
    },
    /// `start + slope (t - t0)`.
    Ramp {
        /// Value at `t0_s`.
        start: f64,
        /// Slope, unit per second.
        slope_per_s: f64,
        /// Time origin, s.
        t0_s: f64,
    },
    /// Switching between signals at fixed instants.
    Piecewise(Piecewise),
}

impl Signal {
    /// The signal's value at time `t_s`.
    pub fn value(&self, t_s: f64) -> f64 {
        match self {
            Self::Constant(v) => *v,
            Self::Sine {
                bias,
                amplitude,
                omega_radps,
                t0_s,
            } => bias + amplitude * libm::sin(omega_radps * (t_s - t0_s)),
            Self::Cosine {
                bias,
                amplitude,
                omega_radps,
                t0_s,
            } => bias + amplitude * libm::cos(omega_radps * (t_s - t0_s)),
            Self::Ramp {
                start,
                slope_per_s,
                t0_s,
            } => start + slope_per_s * (t_s - t0_s),
            Self::Piecewise(p) => p.value(t_s),
        }
    }

    /// Whether the signal is finite at every time in `[t0_s, t1_s]`, from its
    /// parameters: finite parameters can still overflow (an amplitude near
    /// f64::MAX plus a bias, 2 pi times a huge frequency, a steep ramp far
    /// from its origin). Sine and cosine are bounded by `|bias| + |amplitude|`
    /// when their phase is finite; the phase and a ramp are linear in t, so
    /// they are finite over the interval when they are at its ends. A
    /// piecewise signal's pieces are checked over the times they are in force.
    pub fn is_finite_over(&self, t0_s: f64, t1_s: f64) -> bool {
        match self {
            Self::Constant(v) => v.is_finite(),
            Self::Sine {
                bias,
                amplitude,
                omega_radps,
                t0_s: origin,
            }
            | Self::Cosine {
                bias,
                amplitude,
                omega_radps,
                t0_s: origin,
            } => {
                (bias.abs() + amplitude.abs()).is_finite()
                    && (omega_radps * (t0_s - origin)).is_finite()
                    && (omega_radps * (t1_s - origin)).is_finite()
            }
            Self::Ramp { .. } => self.value(t0_s).is_finite() && self.value(t1_s).is_finite(),
            Self::Piecewise(p) => {
                let th = &p.thresholds_s;
                p.pieces.iter().enumerate().all(|(i, piece)| {
                    let lo = if i == 0 { t0_s } else { th[i - 1].max(t0_s) };
                    let hi = th.get(i).map_or(t1_s, |t| t.min(t1_s));
                    lo > hi || piece.is_finite_over(lo, hi)
                })
            }
        }
    }
}

/// Why a [`Piecewise`] signal could not be built.
#[derive(Clone, Debug, PartialEq)]
pub enum PiecewiseError {
    /// `pieces.len()` must be `thresholds_s.len() + 1`.
    PieceCount {
        /// Number of thresholds given.
        thresholds: usize,
        /// Number of pieces given.
        pieces: usize,
    },
    /// Thresholds must be finite and strictly increasing; the index of the first bad one.
    Thresholds {
        /// Index of the first threshold that is not finite or not above its predecessor.
        index: usize,
    },
}

impl fmt::Display for PiecewiseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::PieceCount { thresholds, pieces } => write!(
                f,
                "piecewise signal: {thresholds} thresholds need {} pieces, got {pieces}",
                thresholds + 1
            ),
            Self::Thresholds { index } => write!(
                f,
                "piecewise signal: threshold {index} is not finite or not strictly increasing"
            ),
        }
    }
}

impl std::error::Error for PiecewiseError {}

/// Piecewise signal: piece `i` for `t < thresholds_s[i]` (the first such `i`), the last
/// piece for `t >= ` the last threshold. Invariants checked by [`Piecewise::new`].
#[derive(Clone, Debug, PartialEq)]
pub struct Piecewise {
    thresholds_s: Vec<f64>,
    pieces: Vec<Signal>,
}

impl Piecewise {
    /// Builds a piecewise signal; `pieces.len()` must be `thresholds_s.len() + 1` and the
    /// thresholds finite and strictly increasing.
    pub fn new(thresholds_s: Vec<f64>, pieces: Vec<Signal>) -> Result<Self, PiecewiseError> {
        if pieces.len() != thresholds_s.len() + 1 {
            return Err(PiecewiseError::PieceCount {
                thresholds: thresholds_s.len(),
                pieces: pieces.len(),
            });
        }
        for (i, t) in thresholds_s.iter().enumerate() {
            if !t.is_finite() || (i > 0 && *t <= thresholds_s[i - 1]) {
                return Err(PiecewiseError::Thresholds { index: i });
            }
        }
        Ok(Self {
            thresholds_s,
            pieces,
        })
    }

    /// Piecewise-constant signal: `values[i]` for `t < thresholds_s[i]`, the last value
    /// after the last threshold.
    pub fn constants(thresholds_s: Vec<f64>, values: &[f64]) -> Result<Self, PiecewiseError> {
        Self::new(
            thresholds_s,
            values.iter().map(|v| Signal::Constant(*v)).collect(),
        )
    }

    /// The switching thresholds, s.
    pub fn thresholds_s(&self) -> &[f64] {
        &self.thresholds_s
    }

    /// The pieces (one more than thresholds).
    pub fn pieces(&self) -> &[Signal] {
        &self.pieces
    }

    /// The value at `t_s` (`t_s < threshold` selects the piece before the threshold).
    pub fn value(&self, t_s: f64) -> f64 {
        let i = self
            .thresholds_s
            .iter()
            .position(|th| t_s < *th)
            .unwrap_or(self.thresholds_s.len());
        self.pieces[i].value(t_s)
    }
}

/// What a scenario commands.
#[derive(Clone, Debug, PartialEq)]
pub enum Command {
    /// Closed loop: position reference r(t) for the actuating piston Xo, m.
    Reference(Signal),
    /// Open loop (plant only): servo velocity command v_cmd(t), m/s.
    OpenLoop(Signal),
}

/// A scenario: name, duration, command and load (docs/model.md section 7).
#[derive(Clone, Debug, PartialEq)]
pub struct Scenario {
    name: String,
    duration_s: f64,
    command: Command,
    load_n: Signal,
}

impl Scenario {
    /// A scenario from its parts; the load `load_n` is in N (Ft > 0 opposes extension).
    pub fn new(name: impl Into<String>, duration_s: f64, command: Command, load_n: Signal) -> Self {
        Self {
            name: name.into(),
            duration_s,
            command,
            load_n,
        }
    }

    /// The nominal scenario called `name` (one of [`NOMINAL_NAMES`]), `None` otherwise.
    pub fn by_name(name: &str) -> Option<Self> {
        let constant = Signal::Constant;
        let s = match name {
            "step" => Self::new(
                name,
                6.0,
                Command::Reference(constant(0.050)),
                constant(0.0),
            ),
            "sine" => Self::new(
                name,
                10.0,
                // 0.025 (1 - cos(pi t / 2)) m
                Command::Reference(Signal::Cosine {
                    bias: 0.025,
                    amplitude: -0.025,
                    omega_radps: PI / 2.0,
                    t0_s: 0.0,
                }),
                constant(0.0),
            ),
            "stepload" => Self::new(
                name,
                10.0,
                Command::Reference(constant(0.050)),
                Signal::Piecewise(
                    Piecewise::constants(vec![4.0, 7.0], &[0.0, 800.0, 400.0])
                        .expect("valid by construction"),
                ),
            ),
            "sineload" => Self::new(
                name,
                10.0,
                Command::Reference(constant(0.050)),
                Signal::Sine {
                    bias: 400.0,
                    amplitude: 200.0,
                    omega_radps: PI,
                    t0_s: 0.0,
                },
            ),
            "openloop" => Self::new(
                name,
                4.0,
                Command::OpenLoop(Signal::Piecewise(
                    Piecewise::constants(vec![0.5, 1.0, 1.5, 1.75], &[0.04, 0.0, -0.02, 0.04, 0.0])
                        .expect("valid by construction"),
                )),
                Signal::Piecewise(
                    Piecewise::new(
                        vec![2.0, 3.0],
                        vec![
                            constant(0.0),
                            constant(800.0),
                            Signal::Sine {
                                bias: 200.0,
                                amplitude: 300.0,
                                omega_radps: 4.0 * PI,
                                t0_s: 3.0,
                            },
                        ],
                    )
                    .expect("valid by construction"),
                ),
            ),
            _ => return None,
        };
        Some(s)
    }

    /// All nominal scenarios, in the order of [`NOMINAL_NAMES`].
    pub fn nominal() -> Vec<Self> {
        NOMINAL_NAMES
            .iter()
            .filter_map(|n| Self::by_name(n))
            .collect()
    }

    /// The scenario's name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Duration T, s.
    pub fn duration_s(&self) -> f64 {
        self.duration_s
    }

    /// Number of plant steps of length `dt_s` that cover the duration (rounded).
    pub fn n_steps(&self, dt_s: f64) -> u64 {
        libm::round(self.duration_s / dt_s) as u64
    }

    /// The command (reference or open-loop velocity).
    pub fn command(&self) -> &Command {
        &self.command
    }

    /// The load signal, N.
    pub fn load(&self) -> &Signal {
        &self.load_n
    }

    /// True for an open-loop (plant only) scenario.
    pub fn is_open_loop(&self) -> bool {
        matches!(self.command, Command::OpenLoop(_))
    }

    /// Position reference r(t), m; `None` for an open-loop scenario.
    pub fn reference_m(&self, t_s: f64) -> Option<f64> {
        match &self.command {
            Command::Reference(s) => Some(s.value(t_s)),
            Command::OpenLoop(_) => None,
        }
    }

    /// Open-loop servo velocity command v_cmd(t), m/s; `None` for a closed-loop scenario.
    pub fn v_cmd_mps(&self, t_s: f64) -> Option<f64> {
        match &self.command {
            Command::OpenLoop(s) => Some(s.value(t_s)),
            Command::Reference(_) => None,
        }
    }

    /// Load force Ft(t), N (Ft > 0 opposes extension).
    pub fn load_n(&self, t_s: f64) -> f64 {
        self.load_n.value(t_s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DT: f64 = 1.0e-4;

    fn at(sc: &Scenario, k: u64) -> (Option<f64>, Option<f64>, f64) {
        let t = tick_time_s(k, DT);
        (sc.reference_m(t), sc.v_cmd_mps(t), sc.load_n(t))
    }

    #[test]
    fn names_round_trip() {
        for name in NOMINAL_NAMES {
            let sc = Scenario::by_name(name).expect("nominal scenario");
            assert_eq!(sc.name(), name);
        }
        assert!(Scenario::by_name("nope").is_none());
        assert_eq!(Scenario::nominal().len(), NOMINAL_NAMES.len());
    }

    #[test]
    fn durations_and_steps() {
        for (name, t, n) in [
            ("step", 6.0, 60_000),
            ("sine", 10.0, 100_000),
            ("stepload", 10.0, 100_000),
            ("sineload", 10.0, 100_000),
            ("openloop", 4.0, 40_000),
        ] {
            let sc = Scenario::by_name(name).unwrap();
            assert_eq!(sc.duration_s(), t);
            assert_eq!(sc.n_steps(DT), n);
            assert_eq!(sc.is_open_loop(), name == "openloop");
        }
    }

    #[test]
    fn step_and_sine() {
        let step = Scenario::by_name("step").unwrap();
        assert_eq!(at(&step, 0), (Some(0.05), None, 0.0));
        assert_eq!(at(&step, 59_999), (Some(0.05), None, 0.0));

        let sine = Scenario::by_name("sine").unwrap();
        assert_eq!(sine.reference_m(0.0), Some(0.0));
        for t in [0.3, 1.0, 2.0, 3.7] {
            let want = 0.025 * (1.0 - (PI * t / 2.0).cos());
            assert!((sine.reference_m(t).unwrap() - want).abs() < 1e-17);
        }
        assert!((sine.reference_m(2.0).unwrap() - 0.05).abs() < 1e-17);
        assert_eq!(sine.load_n(1.0), 0.0);
    }

    #[test]
    fn stepload_switches_at_t_k_less_than_threshold() {
        let sc = Scenario::by_name("stepload").unwrap();
        // t_k is exactly 4.0 and 7.0 at k = 40 000 and 70 000 (docs/model.md section 7).
        assert_eq!(tick_time_s(40_000, DT), 4.0);
        assert_eq!(tick_time_s(70_000, DT), 7.0);
        assert_eq!(at(&sc, 0).2, 0.0);
        assert_eq!(at(&sc, 39_999).2, 0.0);
        assert_eq!(at(&sc, 40_000).2, 800.0);
        assert_eq!(at(&sc, 69_999).2, 800.0);
        assert_eq!(at(&sc, 70_000).2, 400.0);
        assert_eq!(at(&sc, 99_999).2, 400.0);
        assert_eq!(at(&sc, 50_000).0, Some(0.05));
    }

    #[test]
    fn sineload() {
        let sc = Scenario::by_name("sineload").unwrap();
        assert_eq!(sc.load_n(0.0), 400.0);
        assert!((sc.load_n(0.5) - 600.0).abs() < 1e-12);
        assert!((sc.load_n(1.5) - 200.0).abs() < 1e-12);
        assert_eq!(sc.reference_m(3.0), Some(0.05));
    }

    #[test]
    fn openloop_profile() {
        let sc = Scenario::by_name("openloop").unwrap();
        assert_eq!(sc.reference_m(0.0), None);
        let v = |k| at(&sc, k).1.unwrap();
        assert_eq!(v(0), 0.04);
        assert_eq!(v(4_999), 0.04);
        assert_eq!(v(5_000), 0.0);
        assert_eq!(v(9_999), 0.0);
        assert_eq!(v(10_000), -0.02);
        assert_eq!(v(14_999), -0.02);
        assert_eq!(v(15_000), 0.04);
        assert_eq!(v(17_499), 0.04);
        assert_eq!(v(17_500), 0.0);
        assert_eq!(v(39_999), 0.0);
        let f = |k| at(&sc, k).2;
        assert_eq!(f(19_999), 0.0);
        assert_eq!(f(20_000), 800.0);
        assert_eq!(f(29_999), 800.0);
        assert_eq!(f(30_000), 200.0); // 300 sin(0) + 200
        let t = tick_time_s(31_250, DT); // quarter period of the 2 Hz sine
        assert!((sc.load_n(t) - 500.0).abs() < 1e-9);
    }

    #[test]
    fn finite_parameters_that_overflow_are_found() {
        let sine = |bias: f64, amplitude: f64, omega_radps: f64, t0_s: f64| Signal::Sine {
            bias,
            amplitude,
            omega_radps,
            t0_s,
        };
        assert!(sine(400.0, 200.0, PI, 0.0).is_finite_over(0.0, 10.0));
        assert!(!sine(1e308, 1e308, 1.0, 0.0).is_finite_over(0.0, 10.0));
        assert!(!sine(0.0, 1.0, f64::INFINITY, 0.0).is_finite_over(0.0, 10.0));
        assert!(!sine(0.0, 1.0, 1e300, -1e10).is_finite_over(0.0, 10.0));
        let ramp = Signal::Ramp {
            start: 0.0,
            slope_per_s: 1e306,
            t0_s: 0.0,
        };
        assert!(ramp.is_finite_over(0.0, 10.0));
        assert!(!ramp.is_finite_over(0.0, 1000.0));
        // A piece only counts where it is in force.
        let p = Signal::Piecewise(
            Piecewise::new(vec![1.0], vec![ramp.clone(), Signal::Constant(0.0)]).unwrap(),
        );
        assert!(p.is_finite_over(0.0, 1000.0));
        let late = Signal::Piecewise(
            Piecewise::new(vec![1.0], vec![Signal::Constant(0.0), ramp]).unwrap(),
        );
        assert!(!late.is_finite_over(0.0, 1000.0));
        for sc in Scenario::nominal() {
            let d = sc.duration_s();
            assert!(sc.load().is_finite_over(0.0, d), "{}", sc.name());
        }
    }

    #[test]
    fn piecewise_validation() {
        let c = Signal::Constant;
        assert_eq!(
            Piecewise::new(vec![1.0], vec![c(0.0)]),
            Err(PiecewiseError::PieceCount {
                thresholds: 1,
                pieces: 1
            })
        );
        assert_eq!(
            Piecewise::constants(vec![1.0, 1.0], &[0.0, 1.0, 2.0]),
            Err(PiecewiseError::Thresholds { index: 1 })
        );
        assert_eq!(
            Piecewise::constants(vec![f64::NAN], &[0.0, 1.0]),
            Err(PiecewiseError::Thresholds { index: 0 })
        );
        let p = Piecewise::new(
            vec![1.0],
            vec![
                c(5.0),
                Signal::Ramp {
                    start: 1.0,
                    slope_per_s: 2.0,
                    t0_s: 1.0,
                },
            ],
        )
        .unwrap();
        assert_eq!(p.value(0.999), 5.0);
        assert_eq!(p.value(1.0), 1.0);
        assert_eq!(p.value(2.0), 3.0);
        assert_eq!(
            Piecewise::constants(vec![], &[3.0]).unwrap().value(-1.0),
            3.0
        );
    }
}
