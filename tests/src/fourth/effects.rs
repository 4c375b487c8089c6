//! The effects a rig of this family can carry: two physically different forms
//! for every identifier of plant.md section 12, and four defects outside that
//! vocabulary. Each variant documents its law; [`crate::fourth::rig`]
//! integrates the plant-side ones and [`crate::fourth::sensors`] applies the
//! sensor-side ones.

/// One unmodelled effect with its parameters (SI units).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Effect {
    /// `leakage`, form A: a worn lip seal across the actuating piston that
    /// acts as a turbulent orifice, Q12 = k (1 + |vo|/v_open) dP /
    /// sqrt(|dP| + p_lam) (square-root law above `p_lam`, laminar below), the
    /// lip lifting further with the piston speed.
    LeakOrifice {
        /// Orifice coefficient, m^3/(s Pa^0.5).
        k: f64,
        /// Piston speed at which the opening doubles, m/s.
        v_open: f64,
        /// Laminar-turbulent transition pressure, Pa.
        p_lam: f64,
    },
    /// `leakage`, form B: laminar clearance flow across the power piston
    /// whose gap dilates with the pressure difference (bore breathing); flow
    /// goes with the gap cubed, Q12 = g0 dP (1 + |dP|/p_dil)^3.
    LeakDilatingGap {
        /// Conductance at zero pressure difference, m^3/(s Pa).
        g0: f64,
        /// Pressure difference that doubles the gap, Pa.
        p_dil: f64,
    },
    /// `friction`, form A: LuGre seal friction on the actuating piston with
    /// a Coulomb level that grows with the line pressures (the seal lips are
    /// pressed on), Fc = fc0 + kp (P1+ + P2+), Fs = ratio_s Fc, Stribeck speed
    /// `vs`, bristle stiffness `sigma0` and damping `sigma1`.
    FrictionLuGre {
        /// Coulomb level at zero pressure, N.
        fc0: f64,
        /// Growth of the Coulomb level with P1 + P2, N/Pa.
        kp: f64,
        /// Stiction / Coulomb ratio.
        ratio_s: f64,
        /// Stribeck speed, m/s.
        vs: f64,
        /// Bristle stiffness, N/m.
        sigma0: f64,
        /// Bristle damping, N s/m.
        sigma1: f64,
    },
    /// `friction`, form B: Karnopp stick-slip with a stiction force and a
    /// direction-dependent Coulomb level (rod seals drag more on extension):
    /// inside |vo| < v_eps the piston sticks while the other forces stay
    /// below `f_stat`.
    FrictionKarnopp {
        /// Breakaway (stiction) force, N.
        f_stat: f64,
        /// Coulomb level while extending, N.
        fc_ext: f64,
        /// Coulomb level while retracting, N.
        fc_ret: f64,
        /// Stick band, m/s.
        v_eps: f64,
        /// Damping that holds the piston inside the stick band, N s/m.
        c_stick: f64,
    },
    /// `backlash`, form A: play of +-`half_play` in the ball-screw nut
    /// between the motor (encoder) and the power piston, which has its own
    /// mass and seal drag; contact through a stiff, damped, unilateral
    /// spring.
    BacklashPlay {
        /// Half of the total play, m.
        half_play: f64,
        /// Contact stiffness, N/m.
        k_contact: f64,
        /// Contact damping, N s/m.
        c_contact: f64,
        /// Power piston and rod mass, kg.
        m_piston: f64,
        /// Power piston seal drag, N s/m.
        c_piston: f64,
    },
    /// `backlash`, form B: no play, a compliant coupling with hysteresis (an
    /// elastomer jaw coupling / preloaded nut): force = k_lin d + z + c d',
    /// where z is a Dahl friction force (dz = sigma (1 - z/f_dahl sgn d') d').
    BacklashHysteresisCoupling {
        /// Linear stiffness, N/m.
        k_lin: f64,
        /// Dahl initial stiffness, N/m.
        sigma: f64,
        /// Dahl saturation force, N.
        f_dahl: f64,
        /// Coupling damping, N s/m.
        c_coupling: f64,
        /// Power piston and rod mass, kg.
        m_piston: f64,
        /// Power piston seal drag, N s/m.
        c_piston: f64,
    },
    /// `air`, form A: free air in both lines, isothermal, that dissolves
    /// into the oil (Henry's law: equilibrium free air a_tot - henry Pabs)
    /// slowly under pressure and comes out of solution faster when the
    /// pressure falls.
    AirDissolving {
        /// Total air per line, normal volume at P_atm, m^3.
        a_tot: f64,
        /// Dissolution capacity, normal m^3 per Pa absolute.
        henry: f64,
        /// Time constant of release (pressure falling), s.
        tau_release: f64,
        /// Time constant of dissolution (pressure rising), s.
        tau_dissolve: f64,
    },
    /// `air`, form B: one trapped adiabatic air pocket at a high point of
    /// hose 1, Vb = vb_ref (p_ref_abs / Pabs)^(1/kappa), fixed gas mass.
    AirPocket {
        /// Pocket volume at `p_ref_abs`, m^3.
        vb_ref: f64,
        /// Reference absolute pressure, Pa.
        p_ref_abs: f64,
        /// Polytropic index of the pocket.
        kappa: f64,
    },
    /// `sensor_delay`, form A: the LVDT's demodulator, a 2nd-order
    /// Butterworth low-pass followed by a transport delay (the digital
    /// pipeline of the conditioning electronics).
    LvdtFilterDelay {
        /// Filter cut-off, Hz.
        f_c_hz: f64,
        /// Transport delay, s (a multiple of the plant step).
        delay_s: f64,
    },
    /// `sensor_delay`, form B: pressure transducers behind snubbers: each
    /// reading follows its line pressure through a damped 2nd-order membrane.
    PressureMembrane {
        /// Natural frequency, Hz.
        f_n_hz: f64,
        /// Damping ratio.
        zeta: f64,
    },
    /// `motor_limit`, form A: the servo drive's PI speed loop (with
    /// acceleration feed-forward from its first-order command shaping) acting
    /// on the reflected inertia, its force limited by the current limit; the
    /// integrator keeps integrating while the current is limited (windup).
    DriveCurrentLimit {
        /// Reflected inertia of motor and screw, kg.
        m_eq: f64,
        /// Current (force) limit, N.
        f_max: f64,
        /// Speed-loop proportional gain, N s/m.
        kv: f64,
        /// Speed-loop integral gain, N/m.
        ki: f64,
        /// Screw and bearing viscous loss, N s/m.
        c_screw: f64,
    },
    /// `motor_limit`, form B: the drive's ramp generator limits the
    /// acceleration, and the bus voltage caps the speed lower the more force
    /// the motor must deliver (back-EMF plus resistive drop):
    /// v_top = v_max (1 - F_motoring / f_stall).
    DriveSlewVoltage {
        /// Acceleration limit, m/s^2.
        a_max: f64,
        /// Force at which the speed ceiling reaches zero, N.
        f_stall: f64,
    },
    /// `hose_hysteresis`, form A: a Bouc-Wen element in each hose wall,
    /// extra wall volume c_h p_z z with dz = dP/p_z (1 - |z|^n (beta sgn(dP z)
    /// + gamma)): full extra compliance after a reversal, none once yielded.
    HoseBoucWen {
        /// Extra compliance right after a reversal, m^3/Pa.
        c_h: f64,
        /// Pressure scale of the loop, Pa.
        p_z: f64,
        /// Bouc-Wen beta.
        beta: f64,
        /// Bouc-Wen gamma.
        gamma: f64,
        /// Bouc-Wen exponent.
        n: f64,
    },
    /// `hose_hysteresis`, form B: a Prandtl-Ishlinskii stack of five
    /// elastic-perfectly-plastic (stop) elements in each hose wall (fibre
    /// braid slipping in the cover): element i adds compliance c_i until
    /// the pressure has moved r_i away from its last reversal.
    HoseStops {
        /// Yield widths, Pa.
        r: [f64; 5],
        /// Compliances, m^3/Pa.
        c: [f64; 5],
    },
    /// `accumulator_thermal`, form A: ideal gas exchanging heat linearly with
    /// a wall of finite heat capacity, the wall exchanging with the ambient.
    AccumulatorWall {
        /// Gas-wall time constant, s.
        tau_gw: f64,
        /// Wall heat capacity / gas heat capacity.
        wall_ratio: f64,
        /// Wall-ambient time constant, s.
        tau_wa: f64,
    },
    /// `accumulator_thermal`, form B: van der Waals nitrogen with natural
    /// convection to a wall at ambient temperature, heat flow
    /// k_nc |dT|^(1/3) dT (fast for large, slow for small differences).
    AccumulatorConvection {
        /// Convection coefficient, W/K^(4/3).
        k_nc: f64,
        /// Van der Waals a, Pa m^6/mol^2.
        a_vdw: f64,
        /// Van der Waals b, m^3/mol.
        b_vdw: f64,
    },
    /// `sensor_calibration`, form A: the LVDT's gain is off and its
    /// characteristic bends cubically towards the ends of its linear range:
    /// reading = x (1 + gain_err) - cubic ((x - center)/half_span)^3.
    LvdtNonlinear {
        /// Relative gain error.
        gain_err: f64,
        /// Cubic deviation at center +- half_span, m.
        cubic: f64,
        /// Centre of the characteristic, m.
        center: f64,
        /// Half span, m.
        half_span: f64,
    },
    /// `sensor_calibration`, form B: the line-1 pressure transducer's output
    /// stage saturates softly and has an offset:
    /// reading = p_sat tanh(P1/p_sat) + offset.
    P1Saturating {
        /// Saturation scale, Pa.
        p_sat: f64,
        /// Offset, Pa.
        offset: f64,
    },
    /// `parameters`: the rig's own parameters are scaled by these factors.
    ParamScale {
        /// Moving mass factor.
        m: f64,
        /// Bulk modulus factor.
        beta_e: f64,
        /// Hose compliance factor (Ce0, Cf0, Cs0 alike).
        hose_c: f64,
        /// Servo time constant factor.
        tau_m: f64,
        /// Accumulator gas volume factor.
        v_gas0: f64,
        /// Viscous damping factor.
        c_visc: f64,
    },
    /// Outside the vocabulary: a return spring pulling the actuating piston
    /// towards `x0`.
    CentringSpring {
        /// Stiffness, N/m.
        k: f64,
        /// Neutral position, m.
        x0: f64,
    },
    /// Outside the vocabulary: the LVDT's offset drifts linearly in time
    /// (electronics warming up).
    LvdtDrift {
        /// Drift rate, m/s.
        rate: f64,
    },
    /// Outside the vocabulary: a seeping relief valve from line 1 to tank
    /// opening at `p_crack`, Q = g (P1 - p_crack)+.
    ReliefToTank {
        /// Cracking pressure, Pa.
        p_crack: f64,
        /// Conductance above cracking, m^3/(s Pa).
        g: f64,
    },
    /// Outside the vocabulary: hose 2 tearing slowly from `t0`: a leak to
    /// tank whose conductance grows linearly, Q = g_rate (t - t0)+ P2.
    HoseRupture {
        /// Onset, s.
        t0: f64,
        /// Growth of the conductance, m^3/(s Pa s).
        g_rate: f64,
    },
}

impl Effect {
    /// Short name of the form (used in the report).
    pub fn form(&self) -> &'static str {
        match self {
            Self::LeakOrifice { .. } => "orifice seal leak, opening with speed",
            Self::LeakDilatingGap { .. } => "laminar gap leak, gap dilating with dP",
            Self::FrictionLuGre { .. } => "LuGre, pressure-dependent levels",
            Self::FrictionKarnopp { .. } => "Karnopp stick-slip, asymmetric Coulomb",
            Self::BacklashPlay { .. } => "nut play with piston mass",
            Self::BacklashHysteresisCoupling { .. } => "compliant coupling with Dahl hysteresis",
            Self::AirDissolving { .. } => "free air with Henry dissolution kinetics",
            Self::AirPocket { .. } => "trapped adiabatic pocket in hose 1",
            Self::LvdtFilterDelay { .. } => "LVDT Butterworth + transport delay",
            Self::PressureMembrane { .. } => "pressure snubber membranes (2nd order)",
            Self::DriveCurrentLimit { .. } => "PI speed loop, current limit, windup",
            Self::DriveSlewVoltage { .. } => "ramp limiter + voltage speed ceiling",
            Self::HoseBoucWen { .. } => "Bouc-Wen hose wall",
            Self::HoseStops { .. } => "Prandtl-Ishlinskii stops in hose wall",
            Self::AccumulatorWall { .. } => "gas-wall-ambient two-node heat transfer",
            Self::AccumulatorConvection { .. } => "van der Waals gas, natural convection",
            Self::LvdtNonlinear { .. } => "LVDT gain error + cubic bend",
            Self::P1Saturating { .. } => "P1 transducer tanh saturation + offset",
            Self::ParamScale { .. } => "parameters scaled",
            Self::CentringSpring { .. } => "centring spring on the load",
            Self::LvdtDrift { .. } => "LVDT offset drifting in time",
            Self::ReliefToTank { .. } => "relief valve line 1 -> tank",
            Self::HoseRupture { .. } => "hose 2 tearing: growing leak to tank",
        }
    }
}
