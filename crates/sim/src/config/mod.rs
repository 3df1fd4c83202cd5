//! The virtual bench's configuration (TOML). Every key has a default, so an
//! empty file, or none, is a complete bench: two counter modules with six
//! instruments each on a 0.8 m centrifuge.
//!
//! The types and their validation only, the preset's name ([`Realism`])
//! among them; what each preset holds, and a file read over its preset
//! (`SimConfig::from_toml`), are in [`crate::realism`], which depends on
//! this module and not the other way round.

mod validate;

use serde::{Deserialize, Serialize};

/// The whole bench.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SimConfig {
    /// The preset the other keys start from (`ideal`, `typical`, `harsh`);
    /// keys given beside it override the preset's values.
    pub realism: Realism,
    /// Seed of every random process (instrument population, noise, faults).
    pub seed: u64,
    /// Local gravity [m/s²].
    pub g_local_m_s2: f64,
    /// Time: 1 = real time (the hardware's pace), N > 1 = N× faster,
    /// 0 = virtual time in lockstep with the station (reproducible).
    pub speed: f64,
    /// Laboratory temperature [°C].
    pub ambient_c: f64,
    /// Slow drift of the laboratory temperature [°C per hour].
    pub ambient_drift_c_per_h: f64,
    /// Latitude of the laboratory [degrees, north positive]: the vertical
    /// component of the Earth's rate, Ω_E·sin(latitude), adds to a table
    /// spinning counter-clockwise (seen from above) and subtracts from one
    /// spinning clockwise (method.md §5). 0 puts the bench on the equator
    /// (no vertical Earth rate).
    pub latitude_deg: f64,
    /// Counter modules (6 instruments each).
    pub modules: usize,
    /// Reference clock of reciprocal counting [Hz].
    pub reference_hz: f64,
    /// The centrifuge.
    pub centrifuge: TableConfig,
    /// How the instruments' true coefficients are drawn.
    pub instruments: PopulationConfig,
    /// Faults to inject.
    pub faults: FaultConfig,
    /// A temperature chamber around the instruments (absent: the room).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub chamber: Option<crate::chamber::ChamberSimConfig>,
}

impl Default for SimConfig {
    fn default() -> Self {
        SimConfig {
            realism: Realism::Ideal,
            seed: 1,
            g_local_m_s2: spinbench_analysis::STANDARD_GRAVITY_M_S2,
            speed: 1.0,
            ambient_c: 23.0,
            ambient_drift_c_per_h: 0.0,
            latitude_deg: 0.0,
            modules: 2,
            reference_hz: 100e6,
            centrifuge: TableConfig::default(),
            instruments: PopulationConfig::default(),
            faults: FaultConfig::default(),
            chamber: None,
        }
    }
}

/// Controller language of the simulated centrifuge.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum SimDialect {
    /// ACUTROL SCPI-style tree (abbreviations accepted).
    #[default]
    Acutrol,
    /// Short mnemonics (`JOG`, `STO`, `RATE?`) in rpm, for the configurable line dialect.
    Mnemonic,
}

/// The centrifuge.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TableConfig {
    /// Drawing radius R0 of every fixture position [m].
    pub arm_radius_m: f64,
    /// Standard deviation of a position's true radius about R0 [mm].
    pub radius_scatter_mm: f64,
    /// The proof mass sits this far off the fixture's centre: the effective
    /// radius is larger by it in one mounting and smaller in the other [mm].
    pub proof_mass_offset_mm: f64,
    /// Rate limit [deg/s].
    pub max_rate_deg_s: f64,
    /// Angular acceleration limit [deg/s²].
    pub max_accel_deg_s2: f64,
    /// Natural frequency of the rate loop [Hz].
    pub loop_natural_hz: f64,
    /// Damping ratio of the rate loop (0.6 gives about 10 % overshoot).
    pub loop_damping: f64,
    /// Once-per-revolution rate ripple [ppm of the rate].
    pub ripple_ppm: f64,
    /// Slow rate wander [ppm of the rate, RMS].
    pub wander_ppm: f64,
    /// Controller language.
    pub dialect: SimDialect,
    /// Arm stretch k_s: R(ω) = R0 + k_s·ω² [m per (rad/s)²], method.md (13).
    pub arm_stretch_m_per_rad2_s2: f64,
    /// Thermal expansion of the arm [ppm/°C], with the arm's windage heating.
    pub arm_expansion_ppm_per_c: f64,
    /// Tilt of the spin axis from the vertical [µrad]: a once-per-revolution
    /// gravity component g·sin(θ)·cos(ωt) along the radius (method.md §5).
    pub tilt_urad: f64,
    /// Scale error of the controller's rate read-back [ppm].
    pub readback_scale_ppm: f64,
    /// Resolution of the controller's rate read-back [deg/s] (0 = none).
    pub readback_resolution_deg_s: f64,
    /// Gate of the controller's rate measurement [s]: it reports the mean
    /// rate over its last gate.
    pub readback_gate_s: f64,
    /// Windage heating of the arm and the instruments at 100 g (at the
    /// drawing radius) [°C]; it rises with the cube of the rate.
    pub windage_c_at_100g: f64,
    /// Time constant of the windage heating [s].
    pub windage_tau_s: f64,
    /// Speed-dependent systematic disturbances (structural resonances).
    pub disturbances: Vec<Disturbance>,
    /// Each fixture position's radius shifted by this, position 1 first
    /// (a fixture coming loose; positions beyond the list are not shifted) [mm].
    pub position_shifts_mm: Vec<f64>,
}

/// A structural resonance near one speed: every instrument's output shifts
/// by `amplitude_ug` (times its own gain) at `at_g` and less beside it, the
/// same whether the level is reached going up or down.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Disturbance {
    /// Centre, as the acceleration at the drawing radius [g].
    pub at_g: f64,
    /// Half width at half height [g].
    pub width_g: f64,
    /// Shift at the centre, along the instrument's input axis [µg].
    pub amplitude_ug: f64,
}

impl Disturbance {
    /// The shift [µg] at nominal acceleration `nominal_g` (a Lorentzian).
    pub fn shift_ug(&self, nominal_g: f64) -> f64 {
        let x = (nominal_g - self.at_g) / self.width_g;
        self.amplitude_ug / (1.0 + x * x)
    }
}

impl Default for TableConfig {
    fn default() -> Self {
        TableConfig {
            arm_radius_m: 0.8,
            radius_scatter_mm: 0.5,
            proof_mass_offset_mm: 0.15,
            max_rate_deg_s: 2400.0,
            max_accel_deg_s2: 90.0,
            loop_natural_hz: 0.5,
            loop_damping: 0.6,
            ripple_ppm: 5.0,
            wander_ppm: 2.0,
            dialect: SimDialect::Acutrol,
            arm_stretch_m_per_rad2_s2: 0.0,
            arm_expansion_ppm_per_c: 0.0,
            tilt_urad: 0.0,
            readback_scale_ppm: 0.0,
            readback_resolution_deg_s: 0.0,
            readback_gate_s: 1.0,
            windage_c_at_100g: 0.0,
            windage_tau_s: 300.0,
            disturbances: Vec::new(),
            position_shifts_mm: Vec::new(),
        }
    }
}

/// Ranges the instrument population is drawn from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PopulationConfig {
    /// Resonator rest frequency [Hz].
    pub resonator_hz: f64,
    /// Scale factor range [Hz/g].
    pub k1_hz_per_g: [f64; 2],
    /// Bias magnitude limit [g].
    pub k0_max_g: f64,
    /// |k2| range [µg/g²] (sign drawn at random).
    pub k2_abs_ug_per_g2: [f64; 2],
    /// k3 magnitude limit [µg/g³].
    pub k3_max_ug_per_g3: f64,
    /// Cross-axis sensitivity magnitude limit [µg/g].
    pub cross_axis_max_ug_per_g: f64,
    /// White noise of a 1-s dF value, as acceleration [µg].
    pub noise_ug: f64,
    /// Bias random walk [µg per √hour].
    pub bias_walk_ug_per_sqrt_h: f64,
    /// Temperature coefficient of the bias [µg/°C].
    pub temp_coeff_ug_per_c: f64,
    /// Self-heating after power-on [°C] and its time constant [s].
    pub self_heating_c: f64,
    /// Time constant of warm-up [s].
    pub warmup_tau_s: f64,
    /// Warm-up transient of the bias at power-on [µg], decaying with `warmup_tau_s`.
    pub warmup_ug: f64,
    /// Supply current per powered instrument, per rail [A].
    pub current_a: f64,
    /// Odd-quadratic term |Koq| limit (Koq·a·|a|) [µg/g²] (sign at random).
    pub koq_max_ug_per_g2: f64,
    /// Scale-factor asymmetry limit, (K1+ − K1−)/K1 [ppm].
    pub asymmetry_max_ppm: f64,
    /// Scale-factor temperature coefficient limit [ppm/°C].
    pub k1_temp_coeff_ppm_per_c: f64,
    /// Limit of k2's temperature coefficient [µg/g²/°C], drawn from its own
    /// random stream (0: none, and the other draws are as without it).
    pub k2_temp_coeff_ug_per_g2_per_c: f64,
    /// Temperature coefficient of the resonators' common frequency [ppm/°C]:
    /// f1 + f2 tracks the instrument's temperature.
    pub resonator_sum_ppm_per_c: f64,
    /// Low-frequency (1/f-like) noise, RMS as acceleration [µg].
    pub flicker_ug: f64,
    /// Range of each instrument's gain on the disturbances.
    pub disturbance_gain: [f64; 2],
    /// Activity dips drawn for the population (resonator mode crossings).
    pub activity_dips: ActivityDipDraw,
    /// Activity dips given one by one (replace the drawn ones of their resonator).
    pub dips: Vec<DipConfig>,
}

/// How each instrument's activity dips are drawn: each resonator, with
/// probability `probability`, has one mode crossing at the frequency it
/// reaches at an acceleration drawn from `at_g` (resonator 1 rises in
/// mounting P, resonator 2 in N, so the two mountings meet different dips
/// at different levels), of a size and width drawn from their ranges, the
/// sign at random. From its own random stream: a bench without dips draws
/// everything else as before.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ActivityDipDraw {
    /// Chance that a resonator has a dip (0: none).
    pub probability: f64,
    /// Range of the acceleration at which its resonator meets it [g].
    pub at_g: [f64; 2],
    /// Range of its size, the shift of dF at its centre as acceleration [µg].
    pub size_ug: [f64; 2],
    /// Range of its width (the standard deviation of a Gaussian in the
    /// resonator's frequency), as acceleration [g].
    pub width_g: [f64; 2],
}

impl Default for ActivityDipDraw {
    fn default() -> Self {
        ActivityDipDraw {
            probability: 0.0,
            at_g: [10.0, 70.0],
            size_ug: [1_000.0, 20_000.0],
            width_g: [0.3, 2.0],
        }
    }
}

/// One activity dip given in the bench config.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DipConfig {
    /// The instrument.
    pub module: usize,
    /// Its slot (0-based).
    pub slot: usize,
    /// Resonator 1 (met in mounting P) or 2 (met in N).
    pub resonator: u8,
    /// Where: the acceleration at which the resonator reaches it [g] ...
    #[serde(default)]
    pub at_g: Option<f64>,
    /// ... or the resonator frequency itself [Hz].
    #[serde(default)]
    pub at_hz: Option<f64>,
    /// Shift of dF at its centre, as acceleration, signed [µg].
    pub size_ug: f64,
    /// Width (Gaussian standard deviation) as acceleration [g].
    pub width_g: f64,
}

impl Default for PopulationConfig {
    fn default() -> Self {
        PopulationConfig {
            resonator_hz: 30_000.0,
            k1_hz_per_g: [80.0, 140.0],
            k0_max_g: 0.05,
            k2_abs_ug_per_g2: [1.0, 30.0],
            k3_max_ug_per_g3: 0.1,
            cross_axis_max_ug_per_g: 50.0,
            noise_ug: 3.0,
            bias_walk_ug_per_sqrt_h: 5.0,
            temp_coeff_ug_per_c: 20.0,
            self_heating_c: 4.0,
            warmup_tau_s: 120.0,
            warmup_ug: 150.0,
            current_a: 0.04,
            koq_max_ug_per_g2: 0.0,
            asymmetry_max_ppm: 0.0,
            k1_temp_coeff_ppm_per_c: 0.0,
            k2_temp_coeff_ug_per_g2_per_c: 0.0,
            resonator_sum_ppm_per_c: 0.0,
            flicker_ug: 0.0,
            disturbance_gain: [1.0, 1.0],
            activity_dips: ActivityDipDraw::default(),
            dips: Vec::new(),
        }
    }
}

/// An instrument addressed by module and slot (0-based).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SlotRef {
    /// Module index.
    pub module: usize,
    /// Slot on the module, 0–5.
    pub slot: usize,
}

/// Faults to inject; all off by default. Times are simulated seconds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(default, deny_unknown_fields)]
pub struct FaultConfig {
    /// Probability that a bit of the counter-module stream is flipped.
    pub bit_error_rate: f64,
    /// Probability that a byte of the stream is dropped.
    pub byte_drop_rate: f64,
    /// Probability that a whole frame is dropped.
    pub frame_drop_rate: f64,
    /// A module that goes silent at a time: (module, seconds).
    pub module_silent: Option<(usize, f64)>,
    /// Instruments that output nothing.
    pub dead_instruments: Vec<SlotRef>,
    /// An instrument that goes silent at a time (a connector working
    /// loose): (its slot, seconds).
    pub instrument_silent_at: Option<(SlotRef, f64)>,
    /// Instruments with this many times the normal noise.
    pub noisy_instruments: Vec<SlotRef>,
    /// Noise multiplier of noisy instruments (default 1000 if zero).
    pub noisy_factor: f64,
    /// Instruments whose output drifts for ever (a bad unit that never settles).
    pub drifting_instruments: Vec<SlotRef>,
    /// Drift of drifting instruments [µg/s] (default 200 if zero).
    pub drift_ug_per_s: f64,
    /// The centrifuge controller stops answering at this time [s].
    pub centrifuge_silent_at_s: Option<f64>,
    /// The interlocks open at this time [s].
    pub interlock_open_at_s: Option<f64>,
    /// The interlocks open once the table has turned for this long in
    /// all [s]: a fault that meets a run however late the run starts.
    pub interlock_open_after_spin_s: Option<f64>,
    /// The instrument supply trips on over-current at this time [s].
    pub supply_trip_at_s: Option<f64>,
}

/// Fastest virtual time (× real time).
pub const MAX_SPEED: f64 = 1e6;
/// Most fixture positions a bench config may shift.
pub const MAX_POSITION_SHIFTS: usize = 1024;

/// The largest acceleration at which, or width over which, an activity dip is set [g].
pub const MAX_DIP_G: f64 = 1_000.0;
/// The largest activity dip [µg].
pub const MAX_DIP_UG: f64 = 1e6;

/// Most structural disturbances a bench may have.
pub const MAX_DISTURBANCES: usize = 32;
/// Latest time a fault may be scheduled at [s] (one year of simulated time).
pub const MAX_FAULT_TIME_S: f64 = 3.2e7;

/// A configuration the bench cannot run; names the key.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("sim config: {key}: {problem}")]
pub struct SimConfigError {
    /// The key.
    pub key: String,
    /// What is wrong.
    pub problem: String,
}

/// A preset of realism.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Realism {
    /// Today's clean world.
    #[default]
    Ideal,
    /// The published data's signature.
    Typical,
    /// Typical, with drift, a dead and a noisy instrument and line faults.
    Harsh,
}

impl std::str::FromStr for Realism {
    type Err = String;

    fn from_str(text: &str) -> Result<Self, Self::Err> {
        match text.trim().to_ascii_lowercase().as_str() {
            "ideal" => Ok(Realism::Ideal),
            "typical" => Ok(Realism::Typical),
            "harsh" => Ok(Realism::Harsh),
            _ => Err(format!("unknown realism '{text}': ideal, typical or harsh")),
        }
    }
}

impl std::fmt::Display for Realism {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Realism::Ideal => "ideal",
            Realism::Typical => "typical",
            Realism::Harsh => "harsh",
        })
    }
}
