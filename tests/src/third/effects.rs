//! The third family's rig departures: effect forms written from the vocabulary of
//! docs/model.md section 12 and from physics, plus defects outside that vocabulary.
//!
//! Each form is a plain parameter struct; [`super::plant::Rig`] composes them into
//! its right-hand side and [`super::sensors::Sensors`] applies the sensor-side ones.
//! None of them is the project's own form (host-sim) or that of the second
//! ("foreign") family; they were written without reading either.

/// Seal leakage across the actuating piston whose gap widens with the pressure
/// difference: Q = G (1 + |dP| / P_w) dP, dP = P1 - P2, from line 1 to line 2.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Leakage {
    /// Laminar conductance at small dP, m^3/(s Pa).
    pub g_m3pspa: f64,
    /// Pressure difference that doubles the conductance, Pa.
    pub widen_pa: f64,
}

/// LuGre seal friction on the actuating piston, with a Coulomb level that rises
/// with the chamber pressures (pressure-energised seals).
///
/// g(v) = Fc + (Fs - Fc) exp(-(v / v_s)^2), Fc = F0 + k_p (P1 + P2), Fs = r_s Fc;
/// dz/dt = v - sigma0 |v| z / g(v); F = sigma0 z + sigma1 dz/dt.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Friction {
    /// Pressure-independent Coulomb part F0, N.
    pub coulomb_n: f64,
    /// Coulomb force per pascal of P1 + P2, N/Pa.
    pub per_pa_n: f64,
    /// Static over Coulomb ratio r_s, -.
    pub static_ratio: f64,
    /// Stribeck speed v_s, m/s.
    pub stribeck_mps: f64,
    /// Bristle stiffness sigma0, N/m.
    pub sigma0_npm: f64,
    /// Bristle damping sigma1, N s/m.
    pub sigma1_nspm: f64,
}

/// Play in the screw-to-piston coupling with a power piston that has mass and
/// seal friction of its own: the piston crosses the gap when the oil force turns,
/// and is pushed against the nut through a contact stiffness and damping.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Backlash {
    /// Total play, m.
    pub play_m: f64,
    /// Contact (axial) stiffness of screw, nut and coupling, N/m.
    pub stiffness_npm: f64,
    /// Contact damping, N s/m.
    pub damping_nspm: f64,
    /// Power piston and rod mass, kg.
    pub piston_kg: f64,
    /// Power piston seal Coulomb friction, N.
    pub seal_n: f64,
    /// Power piston seal viscous friction, N s/m.
    pub seal_nspm: f64,
}

/// Entrained air as isothermal bubbles that go into solution as the pressure
/// rises: free air V_a(P) = a V (P_atm / P_abs) exp(-(P_abs - P_atm) / P_d),
/// added compliance -dV_a/dP = V_a (1/P_abs + 1/P_d), in both lines.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Air {
    /// Free air volume fraction at atmospheric pressure, -.
    pub fraction: f64,
    /// Dissolution pressure scale P_d, Pa.
    pub dissolve_pa: f64,
}

/// Servo drive torque limit with a voltage (back-EMF) limit: the screw force the
/// motor can give while motoring is F_peak up to the corner speed and falls
/// linearly to zero at the no-load speed; braking is limited to F_peak.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotorLimit {
    /// Peak screw force, N.
    pub peak_n: f64,
    /// Reflected inertia of rotor and screw, as a mass on the screw, kg.
    pub mass_eq_kg: f64,
    /// Speed up to which the peak force is available, m/s.
    pub corner_mps: f64,
    /// No-load speed (no force left), m/s.
    pub no_load_mps: f64,
}

/// Rate-independent hysteresis of both hose walls as a Prandtl-Ishlinskii
/// operator: four play operators on the line pressure with thresholds r_i, each
/// adding a wall compliance w_i while it is dragged by the pressure.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HoseHysteresis {
    /// Thresholds r_i of the play operators, Pa.
    pub thresholds_pa: [f64; 4],
    /// Compliance weights w_i, m^3/Pa.
    pub weights_m3pp: [f64; 4],
}

/// Heat exchange of the accumulator gas with its shell: energy balance of an
/// ideal gas, dT/dt = -(gamma - 1) T (dVg/dt) / Vg + (T_amb - T) / tau,
/// P_abs = P0_abs (V0 / Vg) (T / T_amb).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AccumulatorThermal {
    /// Thermal time constant, s.
    pub tau_s: f64,
    /// Ratio of specific heats of the gas (nitrogen), -.
    pub gamma: f64,
}

/// LVDT signal conditioning with a second-order Butterworth low-pass, and/or a
/// transport delay of the acquisition (whole milliseconds).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SensorLag {
    /// Butterworth corner frequency, Hz (0: no filter).
    pub lvdt_corner_hz: f64,
    /// Transport delay of the LVDT reading, s (rounded to whole 1 ms ticks).
    pub lvdt_delay_s: f64,
}

/// A channel whose calibration is wrong: reading = offset + gain x + quad x^2,
/// applied to the true value before noise and ADC.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Calibration {
    /// Which channel.
    pub channel: Channel,
    /// Gain, - (1 is correct).
    pub gain: f64,
    /// Offset in the channel's unit (m or Pa).
    pub offset: f64,
    /// Quadratic term in 1/unit.
    pub quad: f64,
}

/// A sensor channel of the run log.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Channel {
    /// The LVDT on the actuating piston.
    Lvdt,
    /// The line-1 pressure sensor.
    P1,
    /// The line-2 pressure sensor.
    P2,
}

/// Outside the catalogue: a partly closed needle valve (sharp-edged orifice) in
/// line 1 at the power cylinder's port. Q = K dP / sqrt(|dP| + P_t),
/// K = Cd A sqrt(2 / rho); the line-1 pressure sensor sits at that port, upstream
/// of the valve.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Restriction {
    /// Discharge coefficient times area, m^2.
    pub cd_area_m2: f64,
    /// Oil density, kg/m^3.
    pub rho_kgpm3: f64,
    /// Laminar transition pressure P_t, Pa.
    pub transition_pa: f64,
}

/// Outside the catalogue: mains pickup on the drive's analogue speed reference,
/// a sine added to the speed command inside the drive.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriveRipple {
    /// Amplitude, m/s.
    pub amplitude_mps: f64,
    /// Frequency, Hz.
    pub freq_hz: f64,
}

/// Outside the catalogue: a loose LVDT connector. At random instants (Poisson)
/// the conditioner holds its last output for a random time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Dropout {
    /// Mean number of dropouts per second, 1/s.
    pub rate_hz: f64,
    /// Shortest hold, s.
    pub min_s: f64,
    /// Longest hold, s.
    pub max_s: f64,
}

/// Everything a rig of this family may have on top of its parameters.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Effects {
    /// Piston-seal leakage.
    pub leakage: Option<Leakage>,
    /// Seal friction.
    pub friction: Option<Friction>,
    /// Coupling play.
    pub backlash: Option<Backlash>,
    /// Entrained air.
    pub air: Option<Air>,
    /// Drive limit.
    pub motor: Option<MotorLimit>,
    /// Hose wall hysteresis.
    pub hysteresis: Option<HoseHysteresis>,
    /// Accumulator heat exchange.
    pub thermal: Option<AccumulatorThermal>,
    /// LVDT filter and delay.
    pub lag: Option<SensorLag>,
    /// A wrong calibration.
    pub calibration: Option<Calibration>,
    /// Orifice in line 1 (outside the catalogue).
    pub restriction: Option<Restriction>,
    /// Ripple on the drive (outside the catalogue).
    pub ripple: Option<DriveRipple>,
    /// LVDT dropouts (outside the catalogue).
    pub dropout: Option<Dropout>,
}
