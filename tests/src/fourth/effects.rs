//! The effects a rig of this family can carry: two physically different forms
//! for every identifier of plant.md section 12, and four defects outside that
//! vocabulary; then the fifth family's forms (see [`crate::fourth::fifth`]),
//! appended after them. Each variant documents its law; [`crate::fourth::rig`]
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
    // -----------------------------------------------------------------------
    // The fifth family (tests/src/fourth/fifth.rs): forms different from the
    // ones above and from plant.md section 12's named forms and families.
    /// `motor_limit`, fifth family: commutation torque ripple of a
    /// six-step (trapezoidal) brushless motor, growing with speed. The
    /// nominal speed loop asks F_m = m_eq (vc - vi)/tau_m - F_screw (N,
    /// F_screw the hydraulic force on the screw); at each commutation the
    /// force dips; the drive's speed integrator makes up the mean dip, the
    /// rest is dF = -F_m k_v (|vi|/v_ref)/(1 + |vi|/v_ref) cos(2 pi
    /// Xi/pitch)/2, and dvi/dt = (vc - vi)/tau_m + dF/m_eq: the ripple passes
    /// above the speed loop's bandwidth. Why a rig shows it: at speed the
    /// incoming phase's current cannot rise within a commutation interval
    /// (winding inductance against the bus voltage less the back-EMF), so
    /// the torque dips six times per electrical turn, the deeper the faster
    /// and the more loaded the motor runs.
    MotorRipple {
        /// Reflected inertia of motor and screw, kg.
        m_eq: f64,
        /// Relative depth of the dips at high speed.
        k_v: f64,
        /// Speed at which the depth is half of `k_v`, m/s.
        v_ref: f64,
        /// Travel per commutation, m (lead / (6 x pole pairs)).
        pitch: f64,
    },
    /// `motor_limit`, fifth family: the drive's analog speed input has a dead
    /// band and a coarse converter. The drive follows
    /// v_e = sgn(vc) q round(max(|vc| - v_db, 0)/q), m/s, instead of vc
    /// (then the nominal speed loop). Why a rig shows it: drives set a
    /// zero-speed dead band on the analog input so that the motor does not
    /// creep with the input's offset, and read the +-10 V command with a
    /// 10-bit converter: small corrections are lost or quantised.
    MotorDeadband {
        /// Dead band, m/s.
        v_db: f64,
        /// Quantisation step of the command above the dead band, m/s.
        q: f64,
    },
    /// `motor_limit`, fifth family: the motor's torque-speed line from a low
    /// bus voltage and its back-EMF, with the winding inductance. In force
    /// units: the ideal speed loop asks F_dem = clamp(m_eq (vc - vi)/tau_m -
    /// F_screw, +-f_max) (current limit, N); the current loop's voltage
    /// u = clamp((F + f_stall vi/v_noload + tau_e w_c (F_dem - F))/f_stall,
    /// -1, 1) gives tau_e dF/dt = f_stall u - F - f_stall vi/v_noload (F the
    /// motor force, N; f_stall = Kt U_bus/R, v_noload = U_bus/Ke); m_eq
    /// dvi/dt = F + F_screw. Motoring at speed the force collapses, braking
    /// it rises. Why a rig shows it: a motor wound for a 48 V bus run from a
    /// 24 V supply has its no-load speed below the screw's rated speed.
    MotorBackEmf {
        /// Reflected inertia of motor and screw, kg.
        m_eq: f64,
        /// Stall force at full bus voltage, N.
        f_stall: f64,
        /// No-load speed at full bus voltage, m/s.
        v_noload: f64,
        /// Electrical time constant L/R, s.
        tau_e: f64,
        /// Current-loop bandwidth, rad/s.
        w_c: f64,
        /// Current limit, N.
        f_max: f64,
    },
    /// `hose_hysteresis`, fifth family: a hose wall whose rubber creeps with
    /// a power-law (fractional) spectrum and whose braid slips on the rubber
    /// with a friction that grows with the pressure. Creep: five Kelvin
    /// volumes V_k per hose, dV_k/dt = (c_creep w_k L(P) - V_k)/tau_k, tau_k =
    /// 4, 20, 100, 500, 2500 ms, w_k proportional to tau_k^alpha (sum 1), L of
    /// plant.md section 4. Braid: a play operator y (Pa) with |P - y| <=
    /// r(P) = r0 + mu max(P, 0); the wall volume c_braid y (m^3), so a
    /// rising branch adds c_braid (1 - mu), a falling one c_braid (1 + mu).
    /// Why a rig shows it: elastomer creep has no single time constant, and a
    /// textile braid is held on the rubber by friction that the pressure
    /// itself presses on, so it slips only after a pressure reversal has
    /// grown beyond a pressure-dependent width.
    HoseCreepBraid {
        /// Total extra creep compliance at P = 0, m^3/Pa.
        c_creep: f64,
        /// Power-law exponent of the creep spectrum.
        alpha: f64,
        /// Braid compliance while slipping, m^3/Pa.
        c_braid: f64,
        /// Braid yield at P = 0, Pa.
        r0: f64,
        /// Growth of the yield with the pressure (dimensionless, < 1).
        mu: f64,
    },
    /// `hose_hysteresis`, fifth family: a Preisach wall of 18 smoothed relays
    /// per hose at fixed absolute pressures. Relay (i, j): centre p_lo + i
    /// (p_hi - p_lo)/5 (i = 0..5), half-width h_j = (0.4, 1, 1.6) h_mean, up
    /// at alpha = centre + h_j, down at beta = centre - h_j, volume
    /// v_tot (0.5, 0.33, 0.17)_j / 6 (m^3); its state s in [0, 1] is kept
    /// between u(P) = clamp((P - alpha)/delta, 0, 1) and d(P) = clamp((P -
    /// beta)/delta + 1, 0, 1), and the wall holds sum v s: a switching relay
    /// adds v/delta (m^3/Pa). Why a rig shows it: the reinforcement layers
    /// seat and unseat at definite pressure levels (local buckling of the
    /// wire or textile layers), so the loops depend on where in absolute
    /// pressure they are traced, not only on the last reversal.
    HosePreisach {
        /// Switched volume of all relays of one hose, m^3.
        v_tot: f64,
        /// Lowest relay centre, Pa.
        p_lo: f64,
        /// Highest relay centre, Pa.
        p_hi: f64,
        /// Mean relay half-width, Pa.
        h_mean: f64,
        /// Switching width of a relay, Pa.
        delta: f64,
    },
    /// `backlash`, fifth family: a double (preloaded) ball nut worn in the
    /// much-used middle of the stroke. Its total gap is g(Xi) = g_wear
    /// exp(-((Xi - x_wear)/w_wear)^2) - g_pre (m; negative: preload), each
    /// half a unilateral contact, F = -k_half (d -+ g/2) - c_contact d' when
    /// engaged (d = Xp - Xi), acting on the power piston's own mass. Where
    /// the nut is unworn it is preloaded (stiffness 2 k_half); where it is
    /// worn it has play. Why a rig shows it: a ball screw wears where it
    /// works, and loses its preload there first.
    BacklashWornNut {
        /// Contact stiffness of each nut half, N/m.
        k_half: f64,
        /// Preload interference of the unworn nut (total), m.
        g_pre: f64,
        /// Wear at the centre of the worn zone (total), m.
        g_wear: f64,
        /// Xi at the centre of the worn zone, m.
        x_wear: f64,
        /// Width of the worn zone (Gaussian), m.
        w_wear: f64,
        /// Contact damping, N s/m.
        c_contact: f64,
        /// Nut, power piston and rod mass, kg.
        m_piston: f64,
        /// Power piston seal drag, N s/m.
        c_piston: f64,
    },
    /// `backlash`, fifth family: the nut flange sits in a seat with play
    /// +-half_play, held by the friction of loosened bolts: a Jenkins joint
    /// F_j = -k_joint (d - s) whose slip s moves only while |k_joint (d - s)|
    /// = f_lock, in parallel with stiff unilateral ends k_end beyond
    /// +-half_play, plus c_joint d' (d = Xp - Xi), acting on the power
    /// piston's own mass. Forces below f_lock pass through a stiff joint;
    /// a larger force reversal throws the flange across the play. Why a rig
    /// shows it: flange bolts loosen under cyclic load, and the flange then
    /// shifts in its clearance holes whenever the force overcomes the
    /// remaining clamping friction.
    BacklashLockedPlay {
        /// Half of the play of the seat, m.
        half_play: f64,
        /// Clamping friction, N.
        f_lock: f64,
        /// Stiffness of the clamped joint, N/m.
        k_joint: f64,
        /// Stiffness at the ends of the play, N/m.
        k_end: f64,
        /// Joint damping, N s/m.
        c_joint: f64,
        /// Nut, power piston and rod mass, kg.
        m_piston: f64,
        /// Power piston seal drag, N s/m.
        c_piston: f64,
    },
    /// `air`, fifth family: one bubble in the actuating cylinder's bore
    /// (line 1) exchanging heat with the oil: ideal gas, Vb = n R Tb / Pabs, n
    /// from `v_ref` at `p_ref_abs` and 293.15 K, and dTb/dt = (T0 - Tb)/(1.4
    /// tau_th) + Tb (0.4/1.4) (dP/dt)/Pabs (first law with Newton cooling,
    /// kappa 1.4): adiabatic for fast, isothermal for slow pressure changes.
    /// The line gains Vb/(1.4 Pabs) of compliance and the flow
    /// (Vb/1.4)(T0 - Tb)/(Tb tau_th). Why a rig shows it: a cylinder mounted
    /// with its port low keeps a bubble at the top of its bore after
    /// bleeding, and a bubble pressed flat on the wall exchanges heat in a
    /// fraction of a second.
    AirBubbleThermal {
        /// Bubble volume at `p_ref_abs` and 293.15 K, m^3.
        v_ref: f64,
        /// Reference absolute pressure, Pa.
        p_ref_abs: f64,
        /// Thermal time constant, s.
        tau_th: f64,
    },
    /// `air`, fifth family: an air slug at the actuating cylinder's end of
    /// hose 1 behind the hose's oil column. Line 1 splits: the power side (P1,
    /// the sensor, hose walls and fittings) and the actuating chamber with the
    /// slug (P1b, Vs = v_slug (p_ref_abs/P1b_abs)^(1/kappa)), joined by the
    /// hose's oil column, inertance dQh/dt = (P1 - P1b - resistance Qh) /
    /// inertance (Qh m^3/s, inertance kg/m^4, resistance Pa s/m^3). The
    /// actuating piston feels P1b. Why a rig shows it: air collects at a
    /// high point of a hose that was bled from the other end, and a soft
    /// slug makes the oil column's mass (negligible in a stiff line) ring
    /// against it.
    AirSlug {
        /// Slug volume at `p_ref_abs`, m^3.
        v_slug: f64,
        /// Reference absolute pressure, Pa.
        p_ref_abs: f64,
        /// Polytropic index of the slug.
        kappa: f64,
        /// Inertance of the hose's oil column, kg/m^4.
        inertance: f64,
        /// Its flow resistance (laminar, raised for unsteady flow), Pa s/m^3.
        resistance: f64,
    },
    /// `leakage`, fifth family: an axial score in the actuating cylinder's
    /// bore between x_a and x_b: while the piston seal is over it, line 1
    /// leaks to line 2 laminarly, Q12 = g_max b(Xo) (P1 - P2), m^3/s, b = 1
    /// on the score with raised-sine edges of +-`edge` (the seal's width).
    /// Why a rig shows it: a particle dragged along the bore scores it, and
    /// the seal leaks only where it rides over the groove.
    LeakScoredBore {
        /// Conductance over the score, m^3/(s Pa).
        g_max: f64,
        /// Start of the score (Xo), m.
        x_a: f64,
        /// End of the score (Xo), m.
        x_b: f64,
        /// Half-width of the edges, m.
        edge: f64,
    },
    /// `friction`, fifth family: side-load friction of an eccentric load:
    /// the rod carries its load `ecc` off axis, and the resulting moment
    /// loads the piston and the rod bush, whose span shrinks as the rod
    /// extends: N = n0 + 2 |AA1 P1 - AA2 P2| ecc / (span0 - Xo), N, and
    /// F = -mu N vo / sqrt(vo^2 + v_s^2). Why a rig shows it: a test load
    /// hung on a clevis a few millimetres off the rod's axis, and a bent rod
    /// (n0) press the guides the harder the more the rod is out and loaded.
    FrictionSideLoad {
        /// Friction coefficient of the guides.
        mu: f64,
        /// Normal force without load (bent rod), N.
        n0: f64,
        /// Eccentricity of the load, m.
        ecc: f64,
        /// Guide span at Xo = 0, m.
        span0: f64,
        /// Regularising speed, m/s.
        v_s: f64,
    },
    /// `sensor_delay`, fifth family: the LVDT is read by a conditioning
    /// module with its own clock: it samples Xo at phase + n period (s),
    /// its output appears `transport` later and is held (zero order) until
    /// the next one; the controller and the log read the held value. Why a
    /// rig shows it: an LVDT module on a field bus samples at its own rate,
    /// asynchronous to the board's 1 ms tick.
    LvdtSampleHold {
        /// Sampling period of the module, s.
        period: f64,
        /// Sampling phase, s.
        phase: f64,
        /// Transport delay after each sample, s.
        transport: f64,
    },
    /// `accumulator_thermal`, fifth family: ideal gas exchanging heat with a
    /// wall at ambient temperature by convection that the gas's own motion
    /// drives: h = (C_gas/tau_still) (1 + |Qa|/q_ref), W/K, Qa the gas
    /// volume rate (m^3/s), C_gas n R/(n_poly - 1). Why a rig shows it: a
    /// still gas loses heat slowly by conduction, but a fast stroke of the
    /// bladder stirs the gas and multiplies the heat transfer
    /// (forced convection).
    AccumulatorForcedConvection {
        /// Time constant of the still gas, s.
        tau_still: f64,
        /// Gas volume rate that doubles the transfer, m^3/s.
        q_ref: f64,
    },
    /// `sensor_calibration`, fifth family: the encoder reads the motor, and
    /// the drive converts it with a lead that is not the screw's: the power
    /// piston is at Xp = Xi (1 + lead_err) + wobble sin(2 pi Xi / lead), m,
    /// when the encoder reads Xi (the speed loop closes on the encoder).
    /// The xi_m channel therefore misreads the power piston's position.
    /// Why a rig shows it: a 5.08 mm (0.2 in) screw fitted where the drive
    /// was set up for 5 mm, and a screw mounted slightly eccentric, which
    /// advances unevenly over each turn.
    ScrewLeadError {
        /// Relative lead error.
        lead_err: f64,
        /// Amplitude of the per-turn error, m.
        wobble: f64,
        /// Screw lead, m.
        lead: f64,
    },
    /// `sensor_calibration`, fifth family: the load cell's gain, zero and
    /// odd non-linearity are off: reading = Ft (1 + gain_err) + offset +
    /// cubic (Ft/f_ref)^3, N. Why a rig shows it: a load cell calibrated
    /// with another amplifier, its zero taken with a fixture hanging on it.
    LoadCellError {
        /// Relative gain error.
        gain_err: f64,
        /// Zero offset, N.
        offset: f64,
        /// Cubic deviation at f_ref, N.
        cubic: f64,
        /// Reference force, N.
        f_ref: f64,
    },
    /// `parameters`, fifth family: the parameters [`Effect::ParamScale`] does
    /// not reach: precharge P_acc0, restrictor G_acc, both actuating areas
    /// AA1, AA2, and the hose length (its oil volume), scaled by these
    /// factors. Why a rig shows it: an accumulator recharged without a
    /// gauge, a restrictor partly clogged, a cylinder or hose replaced by a
    /// near size.
    ParamScaleHydraulic {
        /// Accumulator precharge (P2 at rest) factor.
        p_acc0: f64,
        /// Restrictor conductance factor.
        g_acc: f64,
        /// Actuating cylinder areas factor.
        aa: f64,
        /// Hose length factor.
        l: f64,
    },
    /// Outside the vocabulary: a sticky LVDT core. The core slides in its
    /// tube with friction and is dragged by a loose clamp with play
    /// +-half_play: the core position c is kept within Xo +- half_play (a
    /// play operator at every plant step) and the LVDT reads c. Why a rig
    /// shows it: a core clamp loosens, and the core rubs in a bent tube.
    StickyLvdtCore {
        /// Half of the clamp's play, m.
        half_play: f64,
    },
    /// Outside the vocabulary: a ground loop puts mains hum on the line-1
    /// pressure signal: reading += amp sin(2 pi f t + phase) + amp3 sin(6 pi
    /// f t + 3 phase), Pa. Why a rig shows it: the transducer's screen is
    /// earthed at both ends, and the mains frequency is off 50 Hz by a few
    /// hundredths.
    MainsHum {
        /// Amplitude of the fundamental, Pa.
        amp: f64,
        /// Mains frequency, Hz.
        freq_hz: f64,
        /// Amplitude of the third harmonic, Pa.
        amp3: f64,
        /// Phase, rad.
        phase: f64,
    },
    /// Outside the vocabulary: the load is applied through a fixture with
    /// its own mass m_f behind a compliant clevis: the rod feels k_f (Xf -
    /// Xo) + c_f (vf - vo) (towards extension), the fixture m_f dvf/dt =
    /// -Ft - k_f (Xf - Xo) - c_f (vf - vo); the force sensor measures the
    /// loading actuator's Ft. Why a rig shows it: the load cell sits at the
    /// loading cylinder, and between it and the rod hang a heavy adaptor
    /// and a rubber-bushed clevis.
    LoadFixture {
        /// Fixture mass, kg.
        m_f: f64,
        /// Clevis stiffness, N/m.
        k_f: f64,
        /// Clevis damping, N s/m.
        c_f: f64,
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
            Self::MotorRipple { .. } => "commutation torque ripple, speed-dependent",
            Self::MotorDeadband { .. } => "command dead band + quantised input",
            Self::MotorBackEmf { .. } => "back-EMF torque-speed line, inductance",
            Self::HoseCreepBraid { .. } => "power-law creep + pressure-locked braid",
            Self::HosePreisach { .. } => "Preisach relays at fixed pressures",
            Self::BacklashWornNut { .. } => "preloaded nut worn in mid-stroke",
            Self::BacklashLockedPlay { .. } => "friction-locked flange play",
            Self::AirBubbleThermal { .. } => "bubble with heat exchange in line 1",
            Self::AirSlug { .. } => "air slug behind hose-1 oil column",
            Self::LeakScoredBore { .. } => "scored bore: leak over a stroke band",
            Self::FrictionSideLoad { .. } => "side-load friction of eccentric load",
            Self::LvdtSampleHold { .. } => "LVDT asynchronous sample-and-hold",
            Self::AccumulatorForcedConvection { .. } => "gas convection driven by gas motion",
            Self::ScrewLeadError { .. } => "screw lead error (encoder scale)",
            Self::LoadCellError { .. } => "load cell gain, zero, cubic",
            Self::ParamScaleHydraulic { .. } => "precharge, restrictor, areas, hose",
            Self::StickyLvdtCore { .. } => "sticky LVDT core (play in reading)",
            Self::MainsHum { .. } => "mains hum on P1 (ground loop)",
            Self::LoadFixture { .. } => "load through fixture mass and clevis",
        }
    }
}
