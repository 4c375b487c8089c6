//! The supervisor and the per-tick control loop around the controller.
//!
//! [`Supervisor`] is the state machine `idle -> armed -> running`, with `fault`
//! reachable from every state:
//!
//! ```text
//!   idle --arm--> armed --goto/sine/HIL frame--> running --stop--> armed
//!    ^              |                               |
//!    +---disarm-----+-------------disarm------------+
//!   any --fault--> fault --clear--> idle
//! ```
//!
//! A fault latches its bit in [`Faults`] and forces the drive command to zero
//! from the tick on which it is detected until `clear`; a condition that is
//! still present after `clear` trips again on the next tick.
//!
//! [`ControlLoop`] is everything the firmware's control task does per tick,
//! apart from reading the sensors and writing the drive: the sample checks,
//! the reference, the controller step and the gating of the command. It is pure
//! and host-tested; the firmware calls it unchanged.

use dca_core::controller::{Controller, Flags, Output, Sample};

/// Supervisor state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum State {
    /// Drive disabled, command 0; sensors are still checked.
    Idle = 0,
    /// Drive enabled, the controller holds the reference (the position at
    /// arming, or where `stop` froze a motion).
    Armed = 1,
    /// Drive enabled, following a motion (`goto`, `sine`) or HIL frames.
    Running = 2,
    /// A fault latched: command 0 until cleared.
    Fault = 3,
}

impl State {
    /// `idle`, `armed`, `running` or `fault`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Idle => "idle",
            Self::Armed => "armed",
            Self::Running => "running",
            Self::Fault => "fault",
        }
    }

    /// The state with this `u8` value (as sent in HIL frames).
    pub fn from_u8(v: u8) -> Option<Self> {
        [Self::Idle, Self::Armed, Self::Running, Self::Fault]
            .into_iter()
            .find(|s| *s as u8 == v)
    }
}

/// Latched fault bits.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Faults(pub u16);

impl Faults {
    /// A sensor read outside its valid range or not finite (an open LVDT reads a
    /// rail code).
    pub const SENSOR_RANGE: u16 = 1 << 0;
    /// A line pressure above the over-pressure limit.
    pub const OVERPRESSURE: u16 = 1 << 1;
    /// A piston outside the software stroke limits.
    pub const STROKE: u16 = 1 << 2;
    /// The controller saw or produced a non-finite value.
    pub const NON_FINITE: u16 = 1 << 3;
    /// The control task missed its deadline.
    pub const OVERRUN: u16 = 1 << 4;
    /// The last reset was caused by the independent watchdog.
    pub const WATCHDOG: u16 = 1 << 5;
    /// HIL link: a frame was lost, corrupt or late.
    pub const HIL_LINK: u16 = 1 << 6;
    /// The drive command path failed (e.g. a controller could not be designed).
    pub const CONFIG: u16 = 1 << 7;

    /// Every fault bit with its console name, in bit order.
    pub const NAMES: [(u16, &'static str); 8] = [
        (Self::SENSOR_RANGE, "sensor-range"),
        (Self::OVERPRESSURE, "overpressure"),
        (Self::STROKE, "stroke"),
        (Self::NON_FINITE, "non-finite"),
        (Self::OVERRUN, "overrun"),
        (Self::WATCHDOG, "watchdog"),
        (Self::HIL_LINK, "hil-link"),
        (Self::CONFIG, "config"),
    ];

    /// True if any of `bits` is set.
    pub fn has(self, bits: u16) -> bool {
        self.0 & bits != 0
    }

    /// True when no fault is latched.
    pub fn is_empty(self) -> bool {
        self.0 == 0
    }
}

/// Limits the supervisor checks every tick (SI units).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SupervisorLimits {
    /// Valid LVDT reading [min, max], m: outside is a sensor fault.
    pub lvdt_valid_m: [f32; 2],
    /// Valid pressure reading [min, max] (both lines), Pa.
    pub p_valid_pa: [f32; 2],
    /// Valid force reading [min, max], N.
    pub ft_valid_n: [f32; 2],
    /// Over-pressure limit (either line), Pa.
    pub p_max_pa: f32,
    /// Software stroke limits [min, max] of both pistons (Xo and Xi), m.
    pub stroke_m: [f32; 2],
}

impl SupervisorLimits {
    /// Defaults for the sensors of docs/model.md section 5: valid ranges just inside
    /// the ADC rails (codes 0, 1, 4094, 4095 of the default calibration are
    /// outside), over-pressure 9 MPa, stroke -5 ... 105 mm.
    pub const DEFAULT: Self = Self {
        lvdt_valid_m: [-0.0099, 0.1099],
        p_valid_pa: [-1.0e6, 1.0e7],
        ft_valid_n: [-1990.0, 1990.0],
        p_max_pa: 9.0e6,
        stroke_m: [-0.005, 0.105],
    };

    /// Fault bits the sample violates (0 when it is fine).
    pub fn check(&self, s: &Sample) -> u16 {
        let within = |v: f32, r: [f32; 2]| v >= r[0] && v <= r[1];
        let mut f = 0;
        if !(within(s.xo_m, self.lvdt_valid_m)
            && within(s.p1_pa, self.p_valid_pa)
            && within(s.p2_pa, self.p_valid_pa)
            && within(s.ft_n, self.ft_valid_n)
            && s.xi_m.is_finite())
        {
            f |= Faults::SENSOR_RANGE;
        }
        if s.p1_pa > self.p_max_pa || s.p2_pa > self.p_max_pa {
            f |= Faults::OVERPRESSURE;
        }
        // Only finite positions can be judged against the stroke.
        let outside = |v: f32| v.is_finite() && !within(v, self.stroke_m);
        if outside(s.xo_m) || outside(s.xi_m) {
            f |= Faults::STROKE;
        }
        f
    }
}

/// Why a supervisor request was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Refused {
    /// A fault is latched: clear it first.
    Faulted,
    /// The drive is not armed.
    NotArmed,
    /// Only allowed while idle.
    NotIdle,
    /// Nothing to clear.
    NoFault,
}

impl Refused {
    /// A short human-readable reason.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Faulted => "fault latched (see 'fault', then 'clear')",
            Self::NotArmed => "not armed",
            Self::NotIdle => "disarm first",
            Self::NoFault => "no fault to clear",
        }
    }
}

/// The state machine.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Supervisor {
    state: State,
    faults: Faults,
}

impl Default for Supervisor {
    fn default() -> Self {
        Self::new()
    }
}

impl Supervisor {
    /// Idle, no fault.
    pub const fn new() -> Self {
        Self {
            state: State::Idle,
            faults: Faults(0),
        }
    }

    /// The current state.
    pub fn state(&self) -> State {
        self.state
    }

    /// The latched faults.
    pub fn faults(&self) -> Faults {
        self.faults
    }

    /// True in `armed` and `running`: the command may reach the drive.
    pub fn drive_enabled(&self) -> bool {
        matches!(self.state, State::Armed | State::Running)
    }

    /// Latch `bits` (no-op for 0) and enter `fault`.
    pub fn trip(&mut self, bits: u16) {
        if bits != 0 {
            self.faults.0 |= bits;
            self.state = State::Fault;
        }
    }

    /// idle -> armed.
    pub fn arm(&mut self) -> Result<(), Refused> {
        match self.state {
            State::Idle => {
                self.state = State::Armed;
                Ok(())
            }
            State::Fault => Err(Refused::Faulted),
            State::Armed | State::Running => Err(Refused::NotIdle),
        }
    }

    /// armed/running -> idle (a latched fault stays).
    pub fn disarm(&mut self) {
        if self.drive_enabled() {
            self.state = State::Idle;
        }
    }

    /// armed/running -> running.
    pub fn start(&mut self) -> Result<(), Refused> {
        match self.state {
            State::Armed | State::Running => {
                self.state = State::Running;
                Ok(())
            }
            State::Fault => Err(Refused::Faulted),
            State::Idle => Err(Refused::NotArmed),
        }
    }

    /// running -> armed.
    pub fn stop(&mut self) -> Result<(), Refused> {
        match self.state {
            State::Armed | State::Running => {
                self.state = State::Armed;
                Ok(())
            }
            State::Fault => Err(Refused::Faulted),
            State::Idle => Err(Refused::NotArmed),
        }
    }

    /// fault -> idle, all fault bits cleared.
    pub fn clear(&mut self) -> Result<(), Refused> {
        if self.state != State::Fault && self.faults.is_empty() {
            return Err(Refused::NoFault);
        }
        self.faults = Faults(0);
        self.state = State::Idle;
        Ok(())
    }

    /// Require `idle` (for changes that must not happen under control).
    pub fn require_idle(&self) -> Result<(), Refused> {
        match self.state {
            State::Idle | State::Fault => Ok(()),
            _ => Err(Refused::NotIdle),
        }
    }
}

/// Where the position reference comes from when no HIL frame gives it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Reference {
    /// A constant position, m (hold, `goto`).
    Hold(f32),
    /// `x0 + amplitude (1 - cos(2 pi f t))`: starts at x0 at rest and swings
    /// between x0 and x0 + 2 amplitude (the paper's sine scenario's shape).
    Sine {
        /// Start (and lowest) position, m.
        x0_m: f32,
        /// Amplitude, m.
        amplitude_m: f32,
        /// Frequency, Hz.
        freq_hz: f32,
        /// Loop tick at which the sine started.
        k0: u64,
    },
}

impl Reference {
    /// The reference at loop tick `k` with base period `dt_s`, m.
    pub fn value(&self, k: u64, dt_s: f64) -> f32 {
        match *self {
            Self::Hold(x) => x,
            Self::Sine {
                x0_m,
                amplitude_m,
                freq_hz,
                k0,
            } => {
                // Phase in cycles, reduced to [0, 1) in f64 so that it stays exact
                // over long runs.
                let cycles = k.wrapping_sub(k0) as f64 * dt_s * freq_hz as f64;
                let frac = (cycles - libm::floor(cycles)) as f32;
                x0_m + amplitude_m * (1.0 - cos_turns(frac))
            }
        }
    }
}

/// cos(2 pi x) for x in [0, 1): folded to a quarter turn and a Taylor series
/// to the 10th power (error below 5e-7; no tables, unlike `libm::cosf`).
pub fn cos_turns(x: f32) -> f32 {
    // cos is even and 1-periodic in turns: fold to [0, 0.5].
    let t = if x > 0.5 { 1.0 - x } else { x };
    // cos(2 pi t) = -cos(2 pi (0.5 - t)): fold to [0, 0.25].
    let (u, sign) = if t > 0.25 { (0.5 - t, -1.0) } else { (t, 1.0) };
    let th = 2.0 * core::f32::consts::PI * u;
    let z = th * th;
    let c =
        1.0 - z / 2.0 * (1.0 - z / 12.0 * (1.0 - z / 30.0 * (1.0 - z / 56.0 * (1.0 - z / 90.0))));
    sign * c
}

/// What one loop tick produced (everything the firmware drives, logs or sends).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TickOut {
    /// The command for the drive, m/s (0 unless the drive is enabled).
    pub v_cmd_mps: f32,
    /// The reference used this tick, m (the last one when not stepping).
    pub ref_m: f32,
    /// Controller flags of this tick (0 when the controller did not step).
    pub flags: Flags,
    /// Supervisor state after the tick.
    pub state: u8,
    /// Latched faults after the tick.
    pub faults: u16,
}

/// Supervisor, reference and controller: the whole per-tick decision.
#[derive(Clone, Copy, Debug)]
pub struct ControlLoop {
    sup: Supervisor,
    limits: SupervisorLimits,
    /// The designed controller with fresh state, copied in at arming.
    template: Controller,
    /// The controller that runs.
    active: Controller,
    reference: Reference,
    /// Base period, s.
    dt_s: f64,
    /// Loop ticks since boot.
    k: u64,
    last: Sample,
    last_ref_m: f32,
}

impl ControlLoop {
    /// A loop around a designed controller (fresh state), idle.
    pub fn new(controller: Controller, limits: SupervisorLimits, dt_s: f64) -> Self {
        Self {
            sup: Supervisor::new(),
            limits,
            template: controller,
            active: controller,
            reference: Reference::Hold(0.0),
            dt_s,
            k: 0,
            last: Sample::default(),
            last_ref_m: 0.0,
        }
    }

    /// The supervisor.
    pub fn supervisor(&self) -> &Supervisor {
        &self.sup
    }

    /// The supervisor, for trips from outside (overrun, watchdog, link).
    pub fn supervisor_mut(&mut self) -> &mut Supervisor {
        &mut self.sup
    }

    /// The running controller.
    pub fn controller(&self) -> &Controller {
        &self.active
    }

    /// The last sample seen.
    pub fn last_sample(&self) -> &Sample {
        &self.last
    }

    /// The reference of the last tick, m.
    pub fn last_ref_m(&self) -> f32 {
        self.last_ref_m
    }

    /// Loop ticks since boot.
    pub fn ticks(&self) -> u64 {
        self.k
    }

    /// Base period, s.
    pub fn dt_s(&self) -> f64 {
        self.dt_s
    }

    /// The checked limits.
    pub fn limits(&self) -> &SupervisorLimits {
        &self.limits
    }

    /// Replace the designed controller and the limits (only while idle or in
    /// fault: the running controller is never swapped under control).
    pub fn reconfigure(
        &mut self,
        controller: Controller,
        limits: SupervisorLimits,
    ) -> Result<(), Refused> {
        self.sup.require_idle()?;
        self.template = controller;
        self.active = controller;
        self.limits = limits;
        Ok(())
    }

    /// Arm: a fresh controller (bumpless from the next sample) holding the last
    /// measured position.
    pub fn arm(&mut self) -> Result<(), Refused> {
        self.sup.arm()?;
        self.active = self.template;
        self.reference = Reference::Hold(self.last.xo_m);
        Ok(())
    }

    /// Disarm (command 0, drive disabled).
    pub fn disarm(&mut self) {
        self.sup.disarm();
    }

    /// Move to `x_m` (a step of the reference; the controllers limit the speed).
    pub fn goto(&mut self, x_m: f32) -> Result<(), Refused> {
        self.sup.start()?;
        self.reference = Reference::Hold(x_m);
        Ok(())
    }

    /// Start a sine from the current reference: `r = r0 + a (1 - cos(2 pi f t))`.
    pub fn sine(&mut self, amplitude_m: f32, freq_hz: f32) -> Result<(), Refused> {
        self.sup.start()?;
        self.reference = Reference::Sine {
            x0_m: self.reference.value(self.k, self.dt_s),
            amplitude_m,
            freq_hz,
            k0: self.k,
        };
        Ok(())
    }

    /// Stop a motion: hold the reference where it is now.
    pub fn stop(&mut self) -> Result<(), Refused> {
        self.sup.stop()?;
        self.reference = Reference::Hold(self.reference.value(self.k, self.dt_s));
        Ok(())
    }

    /// The reference the next tick would use without a HIL frame, m.
    pub fn reference_now(&self) -> f32 {
        self.reference.value(self.k, self.dt_s)
    }

    /// One base tick. `frame_ref` is the reference of a HIL frame (the loop
    /// then runs on the host's reference and enters `running`); `None` uses the
    /// board's own reference.
    ///
    /// Order: check the sample (a violation trips now, and this tick's command
    /// is already 0); step the controller only while the drive is enabled; trip
    /// on a non-finite controller value; gate the command.
    pub fn tick(&mut self, sample: &Sample, frame_ref: Option<f32>) -> TickOut {
        self.last = *sample;
        self.sup.trip(self.limits.check(sample));
        if frame_ref.is_some() && self.sup.state() == State::Armed {
            // Cannot fail from armed.
            let _ = self.sup.start();
        }
        let r = frame_ref.unwrap_or_else(|| self.reference.value(self.k, self.dt_s));
        self.k = self.k.wrapping_add(1);
        let mut out = Output::default();
        if self.sup.drive_enabled() {
            out = self.active.step(sample, r);
            if out.flags.is_error() || !out.v_cmd_mps.is_finite() {
                self.sup.trip(Faults::NON_FINITE);
            }
        }
        self.last_ref_m = r;
        let v = if self.sup.drive_enabled() {
            out.v_cmd_mps
        } else {
            0.0
        };
        TickOut {
            v_cmd_mps: v,
            ref_m: r,
            flags: out.flags,
            state: self.sup.state() as u8,
            faults: self.sup.faults().0,
        }
    }
}
