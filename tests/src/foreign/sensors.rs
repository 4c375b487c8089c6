//! Realistic sensors of docs/model.md section 5 with a self-contained, seeded RNG.
//!
//! Random numbers: xoshiro256** seeded through splitmix64, Gaussian deviates
//! by the Box-Muller transform (both values of a pair are used).

/// xoshiro256** generator (Blackman and Vigna), seeded by splitmix64.
#[derive(Clone, Debug)]
pub struct Rng {
    s: [u64; 4],
    spare: Option<f64>,
}

fn splitmix64(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

impl Rng {
    /// A generator for `seed`.
    pub fn new(seed: u64) -> Self {
        let mut sm = seed;
        let s = [
            splitmix64(&mut sm),
            splitmix64(&mut sm),
            splitmix64(&mut sm),
            splitmix64(&mut sm),
        ];
        Self { s, spare: None }
    }

    /// Next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        let result = self.s[1].wrapping_mul(5).rotate_left(7).wrapping_mul(9);
        let t = self.s[1] << 17;
        self.s[2] ^= self.s[0];
        self.s[3] ^= self.s[1];
        self.s[1] ^= self.s[2];
        self.s[0] ^= self.s[3];
        self.s[2] ^= t;
        self.s[3] = self.s[3].rotate_left(45);
        result
    }

    /// Uniform in (0, 1].
    pub fn uniform(&mut self) -> f64 {
        ((self.next_u64() >> 11) + 1) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Standard normal deviate.
    pub fn gauss(&mut self) -> f64 {
        if let Some(g) = self.spare.take() {
            return g;
        }
        let r = (-2.0 * self.uniform().ln()).sqrt();
        let th = 2.0 * std::f64::consts::PI * self.uniform();
        self.spare = Some(r * th.sin());
        r * th.cos()
    }
}

/// A 12-bit ADC channel with Gaussian noise before quantisation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Adc {
    /// Lower end of the range.
    pub lo: f64,
    /// Upper end of the range.
    pub hi: f64,
    /// Noise, 1 sigma, in the unit of the signal.
    pub sigma: f64,
}

impl Adc {
    /// LVDT, -10 ... 110 mm, 10 um.
    pub const LVDT: Self = Self {
        lo: -0.010,
        hi: 0.110,
        sigma: 10e-6,
    };
    /// Pressure sensor, 0 ... 10 MPa, 5 kPa.
    pub const PRESSURE: Self = Self {
        lo: 0.0,
        hi: 10.0e6,
        sigma: 5.0e3,
    };
    /// Force sensor, -2000 ... 2000 N, 2 N.
    pub const FORCE: Self = Self {
        lo: -2000.0,
        hi: 2000.0,
        sigma: 2.0,
    };

    /// Convert `v` with the noise deviate `g` (standard normal).
    pub fn read(&self, v: f64, g: f64) -> f64 {
        let span = self.hi - self.lo;
        let code = ((v + self.sigma * g - self.lo) / span * 4096.0)
            .floor()
            .clamp(0.0, 4095.0);
        self.lo + (code + 0.5) * span / 4096.0
    }
}

/// Motor encoder resolution: 10 000 counts/rev on a 2 mm lead, m.
pub const ENCODER_STEP: f64 = 0.2e-6;

/// Encoder reading of `xi`.
pub fn encoder(xi: f64) -> f64 {
    (xi / ENCODER_STEP).floor() * ENCODER_STEP
}

/// Sensor model: exact values or docs/model.md section 5's realistic sensors.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SensorMode {
    /// Every sensor returns the exact signal.
    Ideal,
    /// ADC quantisation, Gaussian noise, encoder quantisation.
    Realistic,
}

/// Analogue signals at a sampling instant, before conversion.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Signals {
    /// Power-piston (motor) position, m.
    pub xi_m: f64,
    /// LVDT position, m.
    pub xo_m: f64,
    /// Line-1 pressure, Pa.
    pub p1_pa: f64,
    /// Line-2 pressure, Pa.
    pub p2_pa: f64,
    /// Load force, N.
    pub ft_n: f64,
}

/// The sensor set with its noise source.
#[derive(Clone, Debug)]
pub struct Sensors {
    mode: SensorMode,
    rng: Rng,
}

impl Sensors {
    /// Sensors of `mode`, noise seeded with `seed`.
    pub fn new(mode: SensorMode, seed: u64) -> Self {
        Self {
            mode,
            rng: Rng::new(seed),
        }
    }

    /// Read all channels (four noise deviates per call in realistic mode, in
    /// the order Xo, P1, P2, Ft).
    pub fn read(&mut self, s: &Signals) -> Signals {
        match self.mode {
            SensorMode::Ideal => *s,
            SensorMode::Realistic => Signals {
                xi_m: encoder(s.xi_m),
                xo_m: Adc::LVDT.read(s.xo_m, self.rng.gauss()),
                p1_pa: Adc::PRESSURE.read(s.p1_pa, self.rng.gauss()),
                p2_pa: Adc::PRESSURE.read(s.p2_pa, self.rng.gauss()),
                ft_n: Adc::FORCE.read(s.ft_n, self.rng.gauss()),
            },
        }
    }
}
