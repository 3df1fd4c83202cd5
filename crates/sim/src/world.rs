//! The simulated bench as one deterministic state machine, advanced in
//! 2.5 ms ticks. Given the same config (seed) and the same commands at the
//! same ticks, it produces the same bytes: that is what makes runs
//! reproducible. The serving layer ([`crate::serve`]) only moves bytes
//! between this world and pseudo-terminals or sockets.
//!
//! **Lockstep** (virtual time, `speed = 0`): the world stands still between
//! the station's steps, so every command lands on a tick that does not
//! depend on how fast either side runs. Nothing moves before the counter
//! modules stream; the last module the station addressed starting its
//! stream produces the first second; after that each rate query of the
//! centrifuge controller (which the station makes once per second, after
//! taking that second's values) is answered for the second just read and
//! then produces the next second, whole, before the reply. Every station
//! command waits for its answer before the station goes on, so commands
//! reach the world between seconds. When no module streams any more, the
//! world runs in real time (a table left spinning slows down).

use crate::config::{SimConfig, SimDialect, SlotRef};
use crate::counter::InputCounter;
use crate::supply::Supply;
use crate::table::Table;
use crate::vba::{ActivityDip, Inputs, Mounting, Vba, VbaTruth};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal, StandardNormal, Uniform};
use serde::Serialize;
use spinbench_wire::centrifuge::acutrol_headers as h;
use spinbench_wire::fmu::{
    INPUTS_PER_MODULE, INSTRUMENTS_PER_MODULE, Message, StatusReply, StreamMode, TICKS_PER_SECOND,
};
use spinbench_wire::scpi::{self, HeaderSpec, parse_line};
use std::collections::VecDeque;

/// Seconds per tick.
pub const TICK_S: f64 = 1.0 / TICKS_PER_SECOND as f64;
/// Current drawn by a powered counter module from the logic supply [A].
const MODULE_CURRENT_A: f64 = 0.15;
/// Seed offsets of the noise and wire-fault random streams ("noise", "wire").
const NOISE_STREAM: u64 = 0x006e_6f69_7365;
const WIRE_STREAM: u64 = 0x7769_7265;
/// Seed offset of the error sources' draws ("errors"): the `ideal`
/// population stays the one it always was.
const ERRORS_STREAM: u64 = 0x0000_6572_726f_7273;
/// The temperature coefficients drawn since the chamber came: their own
/// stream, so a bench without them draws everything else as before.
const TEMPCO_STREAM: u64 = 0x7465_6d70_636f;
/// The activity dips' draws ("dips"): their own stream, likewise.
const DIPS_STREAM: u64 = 0x6469_7073;
/// The Earth's rate [rad/s] (the station's own constant).
pub const EARTH_RATE_RAD_S: f64 = spinbench_analysis::centrifuge::EARTH_RATE_RAD_S;
/// Time constants of the low-frequency noise's relaxation processes [s]:
/// equal shares of variance a decade apart approximate a 1/f spectrum
/// between them.
const FLICKER_TAUS_S: [f64; 4] = [10.0, 100.0, 1_000.0, 10_000.0];
/// Firmware id the simulated modules report.
const FIRMWARE_ID: u16 = 0x5101;

/// Which supply a command is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SupplyId {
    /// The ±15 V instrument supply (channel 1 = +15 V, channel 2 = −15 V).
    Rails,
    /// The +5 V counter-module supply.
    Logic,
}

/// One fixture position on the arm.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Position {
    /// Drawing radius R0 [m].
    pub drawing_radius_m: f64,
    /// True effective radius in mounting P [m], at rest.
    pub radius_p_m: f64,
    /// True effective radius in mounting N [m], at rest.
    pub radius_n_m: f64,
    /// Angle of the position on the arm [rad] (the phase of the tilt's
    /// once-per-revolution gravity component).
    pub azimuth_rad: f64,
}

/// What a perfect per-mounting fit of method.md (2) against |a| would
/// return for one instrument, centrifuge terms included (method.md (15)):
/// k2_P = K2 + c', k2_N = c' − K2, c' = arm stretch + Koq.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PerMountingK2 {
    /// Mounting P [µg/g²].
    pub p_ug_per_g2: f64,
    /// Mounting N [µg/g²].
    pub n_ug_per_g2: f64,
    /// The part common to both: arm stretch c plus Koq [µg/g²].
    pub common_ug_per_g2: f64,
    /// The arm stretch's share of it, c = k_s·g/R² [µg/g²].
    pub arm_stretch_ug_per_g2: f64,
}

/// The centrifuge's and the laboratory's error sources, as the bench has them
/// (the instruments' own are in [`VbaTruth`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CentrifugeTruth {
    /// The preset.
    pub realism: crate::Realism,
    /// Arm stretch k_s [m per (rad/s)²].
    pub arm_stretch_m_per_rad2_s2: f64,
    /// Arm thermal expansion [ppm/°C].
    pub arm_expansion_ppm_per_c: f64,
    /// Spin-axis tilt [µrad].
    pub tilt_urad: f64,
    /// Latitude [deg].
    pub latitude_deg: f64,
    /// Vertical component of the Earth's rate, Ω_E·sin(latitude) [rad/s].
    pub earth_rate_vertical_rad_s: f64,
    /// Rate read-back scale error [ppm].
    pub readback_scale_ppm: f64,
    /// Rate read-back resolution [deg/s].
    pub readback_resolution_deg_s: f64,
    /// Rate read-back gate [s].
    pub readback_gate_s: f64,
    /// Rate wander [ppm RMS].
    pub wander_ppm: f64,
    /// Once-per-revolution ripple [ppm].
    pub ripple_ppm: f64,
    /// Windage heating at 100 g [°C].
    pub windage_c_at_100g: f64,
    /// Laboratory temperature at the start [°C].
    pub ambient_c: f64,
    /// Its drift [°C per hour].
    pub ambient_drift_c_per_h: f64,
    /// Each instrument's self-heating once powered [°C].
    pub self_heating_c: f64,
    /// Structural disturbances.
    pub disturbances: Vec<crate::config::Disturbance>,
}

/// The truth of one instrument, for comparing with what the station measured.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct InstrumentTruth {
    /// Module index.
    pub module: usize,
    /// Slot on the module.
    pub slot: usize,
    /// The instrument's parameters.
    #[serde(flatten)]
    pub vba: VbaTruth,
    /// Its fixture position.
    #[serde(flatten)]
    pub position: Position,
    /// The instrument's own second-order term K2 (even; the IEEE value) [µg/g²].
    pub instrument_k2_ug_per_g2: f64,
    /// What a perfect per-mounting fit would return, centrifuge included.
    pub per_mounting_k2: PerMountingK2,
}

/// Everything the bench knows that the station must find out.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Truth {
    /// Seed of the bench.
    pub seed: u64,
    /// Local gravity [m/s²].
    pub g_local_m_s2: f64,
    /// The centrifuge's error sources.
    pub centrifuge: CentrifugeTruth,
    /// Every instrument.
    pub instruments: Vec<InstrumentTruth>,
}

#[derive(Debug, Clone)]
struct ModuleSim {
    relay_mask: u8,
    streaming: Option<StreamMode>,
    /// Streaming starts on this tick: the next whole second after the
    /// command, so modules started together share one window grid.
    stream_from_tick: u64,
    seq: u16,
    temp_seq: u16,
    inputs: [InputCounter; INPUTS_PER_MODULE],
    overruns: u16,
    rx_crc_errors: u16,
}

/// The bench.
pub struct World {
    config: SimConfig,
    tick: u64,
    noise_rng: ChaCha8Rng,
    wire_rng: ChaCha8Rng,
    /// The centrifuge.
    pub table: Table,
    instruments: Vec<Vba>,
    positions: Vec<Position>,
    modules: Vec<ModuleSim>,
    /// The ±15 V instrument supply.
    pub rails: Supply,
    /// The +5 V counter-module supply.
    pub logic: Supply,
    centrifuge_errors: VecDeque<(i32, String)>,
    centrifuge_silent: bool,
    module_silent: Vec<bool>,
    faults_fired: [bool; 3],
    /// Virtual time in lockstep with the station (`speed = 0`).
    lockstep: bool,
    /// Lockstep: bytes of the seconds produced, per module, for the serving layer.
    outbox: Vec<Vec<u8>>,
    /// Modules the station has sent a frame to.
    addressed: Vec<bool>,
    /// Some module has streamed since the world began.
    has_streamed: bool,
    /// Lockstep: a second has been produced since the streams started.
    lockstep_running: bool,
    /// Lockstep: seconds produced (the serving layer watches it for liveness).
    seconds_produced: u64,
    /// Windage heating of the arm and the instruments now [°C].
    windage_c: f64,
    /// Low-frequency noise state per instrument [g], one per time constant.
    flicker_g: Vec<[f64; 4]>,
    /// The temperature chamber the instruments sit in, if the bench has one.
    chamber: Option<crate::chamber::ChamberModel>,
}

/// Each resonator's activity dip, drawn as `how` says (always the same
/// number of draws, so the stream does not depend on which are kept).
fn draw_dips(
    truth: &VbaTruth,
    how: &crate::config::ActivityDipDraw,
    rng: &mut ChaCha8Rng,
) -> [Option<ActivityDip>; 2] {
    std::array::from_fn(|r| {
        let present = rng.random::<f64>() < how.probability;
        let at_g = draw(rng, how.at_g[0], how.at_g[1]);
        let width_g = draw(rng, how.width_g[0], how.width_g[1]);
        let sign = if rng.random::<bool>() { 1.0 } else { -1.0 };
        let size_ug = sign * draw(rng, how.size_ug[0], how.size_ug[1]);
        present.then(|| ActivityDip::at_acceleration(truth, r as u8 + 1, at_g, width_g, size_ug))
    })
}

fn draw(rng: &mut ChaCha8Rng, lo: f64, hi: f64) -> f64 {
    if hi > lo {
        Uniform::new(lo, hi).map_or(lo, |u| u.sample(rng))
    } else {
        lo
    }
}

impl World {
    /// A bench from a validated config; the population is drawn from the seed.
    pub fn new(config: SimConfig) -> World {
        let mut rng = ChaCha8Rng::seed_from_u64(config.seed);
        let mut errors_rng = ChaCha8Rng::seed_from_u64(config.seed ^ ERRORS_STREAM);
        let mut tempco_rng = ChaCha8Rng::seed_from_u64(config.seed ^ TEMPCO_STREAM);
        let mut dips_rng = ChaCha8Rng::seed_from_u64(config.seed ^ DIPS_STREAM);
        let n = config.modules * INSTRUMENTS_PER_MODULE;
        let p = &config.instruments;
        let t = &config.centrifuge;
        let mut instruments = Vec::with_capacity(n);
        let mut positions = Vec::with_capacity(n);
        for _ in 0..n {
            let sign = if rng.random::<bool>() { 1.0 } else { -1.0 };
            let truth = VbaTruth {
                k0_g: draw(&mut rng, -p.k0_max_g, p.k0_max_g),
                k1_hz_per_g: draw(&mut rng, p.k1_hz_per_g[0], p.k1_hz_per_g[1]),
                k2_ug_per_g2: sign * draw(&mut rng, p.k2_abs_ug_per_g2[0], p.k2_abs_ug_per_g2[1]),
                k3_ug_per_g3: draw(&mut rng, -p.k3_max_ug_per_g3, p.k3_max_ug_per_g3),
                cross_axis_ug_per_g: draw(
                    &mut rng,
                    -p.cross_axis_max_ug_per_g,
                    p.cross_axis_max_ug_per_g,
                ),
                resonator_hz: p.resonator_hz * draw(&mut rng, 0.98, 1.02),
                noise_ug: p.noise_ug,
                bias_walk_ug_per_sqrt_h: p.bias_walk_ug_per_sqrt_h,
                temp_coeff_ug_per_c: p.temp_coeff_ug_per_c * draw(&mut rng, -1.0, 1.0),
                koq_ug_per_g2: draw(&mut errors_rng, -p.koq_max_ug_per_g2, p.koq_max_ug_per_g2),
                asymmetry_ppm: draw(&mut errors_rng, -p.asymmetry_max_ppm, p.asymmetry_max_ppm),
                k1_temp_coeff_ppm_per_c: p.k1_temp_coeff_ppm_per_c
                    * draw(&mut errors_rng, -1.0, 1.0),
                k2_temp_coeff_ug_per_g2_per_c: p.k2_temp_coeff_ug_per_g2_per_c
                    * draw(&mut tempco_rng, -1.0, 1.0),
                resonator_sum_ppm_per_c: p.resonator_sum_ppm_per_c,
                flicker_ug: p.flicker_ug,
                disturbance_gain: draw(
                    &mut errors_rng,
                    p.disturbance_gain[0],
                    p.disturbance_gain[1],
                ),
                dips: [None; 2],
            };
            let truth = VbaTruth {
                dips: draw_dips(&truth, &p.activity_dips, &mut dips_rng),
                ..truth
            };
            instruments.push(Vba::new(truth));
            let scatter: f64 = StandardNormal.sample(&mut rng);
            let shift_mm = t
                .position_shifts_mm
                .get(positions.len())
                .copied()
                .unwrap_or(0.0);
            let centre = t.arm_radius_m + (scatter * t.radius_scatter_mm + shift_mm) * 1e-3;
            let offset = t.proof_mass_offset_mm * 1e-3;
            positions.push(Position {
                drawing_radius_m: t.arm_radius_m,
                radius_p_m: centre + offset,
                radius_n_m: centre - offset,
                azimuth_rad: std::f64::consts::TAU * positions.len() as f64 / n as f64,
            });
        }
        for dip in &p.dips {
            let Some(v) = instruments.get_mut(dip.module * INSTRUMENTS_PER_MODULE + dip.slot)
            else {
                continue;
            };
            let t = &v.truth;
            let d = match (dip.at_g, dip.at_hz) {
                (_, Some(hz)) => {
                    ActivityDip::at_frequency(t, dip.resonator, hz, dip.width_g, dip.size_ug)
                }
                (Some(g), None) => {
                    ActivityDip::at_acceleration(t, dip.resonator, g, dip.width_g, dip.size_ug)
                }
                (None, None) => continue,
            };
            v.truth.dips[usize::from(dip.resonator == 2)] = Some(d);
        }
        let module = ModuleSim {
            relay_mask: 0,
            streaming: None,
            stream_from_tick: 0,
            seq: 0,
            temp_seq: 0,
            inputs: [InputCounter::default(); INPUTS_PER_MODULE],
            overruns: 0,
            rx_crc_errors: 0,
        };
        let mut logic = Supply::new("SPINBENCH,SIM-PSU-5V,0,1.0", 1);
        // The module supply is left on, as on a bench; the instrument rails start off.
        logic.outputs[0].volts = 5.0;
        logic.outputs[0].on = true;
        World {
            noise_rng: ChaCha8Rng::seed_from_u64(config.seed ^ NOISE_STREAM),
            wire_rng: ChaCha8Rng::seed_from_u64(config.seed ^ WIRE_STREAM),
            table: Table::new(config.centrifuge.clone()),
            instruments,
            positions,
            modules: vec![module; config.modules],
            rails: Supply::new("SPINBENCH,SIM-PSU-15V,0,1.0", 2),
            logic,
            centrifuge_errors: VecDeque::new(),
            centrifuge_silent: false,
            module_silent: vec![false; config.modules],
            faults_fired: [false; 3],
            tick: 0,
            lockstep: config.speed == 0.0,
            outbox: vec![Vec::new(); config.modules],
            addressed: vec![false; config.modules],
            has_streamed: false,
            lockstep_running: false,
            seconds_produced: 0,
            windage_c: 0.0,
            chamber: config
                .chamber
                .clone()
                .map(|c| crate::chamber::ChamberModel::new(c, config.ambient_c)),
            flicker_g: vec![[0.0; 4]; n],
            config,
        }
    }

    /// The configuration.
    pub fn config(&self) -> &SimConfig {
        &self.config
    }

    /// Simulated time [s].
    pub fn now_s(&self) -> f64 {
        self.tick as f64 * TICK_S
    }

    /// Ticks elapsed.
    pub fn tick(&self) -> u64 {
        self.tick
    }

    /// Whether the world runs in lockstep with the station (virtual time).
    pub fn lockstep(&self) -> bool {
        self.lockstep
    }

    /// Lockstep: seconds produced so far.
    pub fn seconds_produced(&self) -> u64 {
        self.seconds_produced
    }

    /// Whether any live module streams.
    pub fn streaming_any(&self) -> bool {
        (0..self.modules.len()).any(|m| self.module_alive(m) && self.modules[m].streaming.is_some())
    }

    /// Lockstep: the world runs in real time instead (no module streams
    /// after a run, or a table was set moving before any did).
    pub fn free_running(&self) -> bool {
        let table_moving = self.table.rate_rad_s != 0.0
            || (self.table.rate_mode && self.table.demand_rad_s != 0.0);
        self.lockstep && !self.streaming_any() && (self.has_streamed || table_moving)
    }

    /// Lockstep: take the bytes module `m` produced since the last call.
    pub fn take_outbox(&mut self, m: usize) -> Vec<u8> {
        self.outbox
            .get_mut(m)
            .map(std::mem::take)
            .unwrap_or_default()
    }

    /// Lockstep: whether every module's produced bytes have been taken.
    pub fn outbox_empty(&self) -> bool {
        self.outbox.iter().all(Vec::is_empty)
    }

    /// Lockstep: produce the next whole second (to the next whole-second
    /// tick), its bytes kept for [`take_outbox`](Self::take_outbox).
    pub fn advance_second(&mut self) {
        let per_second = u64::from(TICKS_PER_SECOND);
        let end = (self.tick / per_second + 1) * per_second;
        while self.tick < end {
            let out = self.step();
            for (bytes, outbox) in out.into_iter().zip(&mut self.outbox) {
                outbox.extend(bytes);
            }
        }
        self.seconds_produced += 1;
        self.lockstep_running = true;
    }

    /// Lockstep: the station has taken a second (its rate query): the next one.
    fn lockstep_barrier(&mut self) {
        if self.lockstep && self.lockstep_running && self.streaming_any() {
            self.advance_second();
        }
    }

    /// Lockstep: once every module the station addressed streams, the first second.
    fn lockstep_start(&mut self) {
        let all_streaming = (0..self.modules.len()).all(|m| {
            !self.addressed[m] || !self.module_alive(m) || self.modules[m].streaming.is_some()
        });
        if self.lockstep && !self.lockstep_running && all_streaming && self.streaming_any() {
            self.advance_second();
        }
    }

    /// Number of instruments.
    pub fn instrument_count(&self) -> usize {
        self.instruments.len()
    }

    /// The truth of every instrument.
    pub fn truth(&self) -> Truth {
        let c = &self.config;
        let t = &c.centrifuge;
        Truth {
            seed: c.seed,
            g_local_m_s2: c.g_local_m_s2,
            centrifuge: CentrifugeTruth {
                realism: c.realism,
                arm_stretch_m_per_rad2_s2: t.arm_stretch_m_per_rad2_s2,
                arm_expansion_ppm_per_c: t.arm_expansion_ppm_per_c,
                tilt_urad: t.tilt_urad,
                latitude_deg: c.latitude_deg,
                earth_rate_vertical_rad_s: self.earth_rate_vertical_rad_s(),
                readback_scale_ppm: t.readback_scale_ppm,
                readback_resolution_deg_s: t.readback_resolution_deg_s,
                readback_gate_s: t.readback_gate_s,
                wander_ppm: t.wander_ppm,
                ripple_ppm: t.ripple_ppm,
                windage_c_at_100g: t.windage_c_at_100g,
                ambient_c: c.ambient_c,
                ambient_drift_c_per_h: c.ambient_drift_c_per_h,
                self_heating_c: c.instruments.self_heating_c,
                disturbances: t.disturbances.clone(),
            },
            instruments: self
                .instruments
                .iter()
                .zip(&self.positions)
                .enumerate()
                .map(|(i, (v, p))| {
                    let k2 = v.truth.k2_ug_per_g2;
                    // c = k_s·g/R² (method.md (15)), at the position's radius.
                    let r = 0.5 * (p.radius_p_m + p.radius_n_m);
                    let stretch = t.arm_stretch_m_per_rad2_s2 * c.g_local_m_s2 / (r * r) * 1e6;
                    let common = stretch + v.truth.koq_ug_per_g2;
                    InstrumentTruth {
                        module: i / INSTRUMENTS_PER_MODULE,
                        slot: i % INSTRUMENTS_PER_MODULE,
                        vba: v.truth,
                        position: *p,
                        instrument_k2_ug_per_g2: k2,
                        per_mounting_k2: PerMountingK2 {
                            p_ug_per_g2: k2 + common,
                            n_ug_per_g2: common - k2,
                            common_ug_per_g2: common,
                            arm_stretch_ug_per_g2: stretch,
                        },
                    }
                })
                .collect(),
        }
    }

    /// What a perfect per-mounting fit of method.md (2) of `order` over the
    /// nominal levels `levels_g` (at the drawing radius) returns for
    /// instrument `i` in `mount`: the instrument's noise-free smooth output
    /// (its physics without its activity dips, which are not part of its
    /// k2) at the true input of each level on a perfect arm of this
    /// centrifuge (arm stretch and the Earth's rate, a table turning
    /// counter-clockwise, but none of the table's structural resonances,
    /// which are the station's error, not the instrument's), fitted against
    /// the input the station computes (the rate, the position's radius).
    /// Unlike the sum K2 ± (c + Koq) this holds every cross term (k3 times
    /// the stretch is ~0.02 µg/g² at 8 µg/g² of stretch). `None` if it
    /// cannot fit.
    pub fn perfect_fit_k2(
        &self,
        i: usize,
        mount: spinbench_analysis::Mount,
        levels_g: &[f64],
        order: spinbench_analysis::ModelOrder,
    ) -> Option<f64> {
        use spinbench_analysis::{Mount, Point, model::fit_mounting};
        // The instrument as built: no random walk, warm-up or temperature
        // (the world may have run on in real time since the run ended).
        let v = self.instruments.get(i)?.without_dips();
        let p = self.positions.get(i)?;
        let (g, t) = (self.config.g_local_m_s2, &self.config.centrifuge);
        let r = match mount {
            Mount::P => p.radius_p_m,
            Mount::N => p.radius_n_m,
        };
        let points: Vec<Point> = levels_g
            .iter()
            .map(|&level| {
                let w2 = level * g / t.arm_radius_m;
                let inertial = w2.sqrt() + self.earth_rate_vertical_rad_s();
                let a_true = if level == 0.0 {
                    0.0
                } else {
                    inertial * inertial * (r + t.arm_stretch_m_per_rad2_s2 * w2) / g
                };
                let (f1, f2) = v.resonators(&Inputs {
                    a_g: mount.input_sign() * a_true,
                    ..Inputs::default()
                });
                Point {
                    mount,
                    g_nominal: level,
                    g_applied: w2 * r / g,
                    output: f1 - f2,
                    direction: None,
                }
            })
            .collect();
        fit_mounting(&points, mount, order, "perfect fit")
            .ok()?
            .fit
            .k2_ug_per_g2
    }

    /// The vertical component of the Earth's rate here [rad/s].
    pub fn earth_rate_vertical_rad_s(&self) -> f64 {
        EARTH_RATE_RAD_S * self.config.latitude_deg.to_radians().sin()
    }

    /// The laboratory's temperature now [°C].
    pub fn ambient_c(&self) -> f64 {
        self.config.ambient_c + self.config.ambient_drift_c_per_h * self.now_s() / 3600.0
    }

    /// What the instruments' surroundings are at now [°C]: the chamber's
    /// air as they feel it (lagged), or the laboratory.
    pub fn surroundings_c(&self) -> f64 {
        self.chamber
            .as_ref()
            .map_or_else(|| self.ambient_c(), |c| c.instrument_air_c)
    }

    /// The temperature chamber, if the bench has one.
    pub fn chamber(&self) -> Option<&crate::chamber::ChamberModel> {
        self.chamber.as_ref()
    }

    /// The temperature chamber, to answer its controller's requests.
    pub fn chamber_mut(&mut self) -> Option<&mut crate::chamber::ChamberModel> {
        self.chamber.as_mut()
    }

    /// Windage heating of the arm and the instruments now [°C].
    pub fn windage_c(&self) -> f64 {
        self.windage_c
    }

    /// Temperature of instrument `i` now [°C]: the laboratory, its
    /// self-heating since power-on, and the windage.
    pub fn instrument_temperature_c(&self, i: usize) -> f64 {
        let pc = &self.config.instruments;
        self.instruments.get(i).map_or(f64::NAN, |v| {
            v.temperature_c(
                self.now_s(),
                self.surroundings_c(),
                pc.self_heating_c,
                pc.warmup_tau_s,
            ) + self.windage_c
        })
    }

    /// Mount instrument `index` (module·6 + slot) as `mounting` (the operator's hands).
    pub fn set_mounting(&mut self, index: usize, mounting: Mounting) {
        if let Some(v) = self.instruments.get_mut(index) {
            v.mounting = mounting;
        }
    }

    /// The centrifuge controller answers again (a silence fault ends, e.g.
    /// its cable is plugged back in).
    pub fn end_centrifuge_silence(&mut self) {
        self.config.faults.centrifuge_silent_at_s = None;
        self.centrifuge_silent = false;
    }

    /// Mount every instrument the same way.
    pub fn set_all_mountings(&mut self, mounting: Mounting) {
        for v in &mut self.instruments {
            v.mounting = mounting;
        }
    }

    fn rails_on(&self) -> bool {
        self.rails.outputs.iter().all(|o| o.on)
    }

    fn module_alive(&self, m: usize) -> bool {
        self.logic.outputs[0].on && !self.module_silent.get(m).copied().unwrap_or(true)
    }

    fn is(&self, list: &[SlotRef], i: usize) -> bool {
        list.iter()
            .any(|s| s.module * INSTRUMENTS_PER_MODULE + s.slot == i)
    }

    /// Module `m`'s relay mask (bit i = instrument i powered), if it exists.
    pub fn relay_mask(&self, m: usize) -> Option<u8> {
        self.modules.get(m).map(|module| module.relay_mask)
    }

    /// Whether module `m` is streaming.
    pub fn streaming(&self, m: usize) -> bool {
        self.modules
            .get(m)
            .is_some_and(|module| module.streaming.is_some())
    }

    /// Whether instrument `i` is powered: rails on and its relay closed.
    pub fn powered(&self, i: usize) -> bool {
        let m = i / INSTRUMENTS_PER_MODULE;
        let bit = 1u8 << (i % INSTRUMENTS_PER_MODULE);
        self.rails_on() && self.module_alive(m) && self.modules[m].relay_mask & bit != 0
    }

    /// Load current of each rails channel [A].
    pub fn rail_currents(&self) -> Vec<f64> {
        let n = (0..self.instruments.len())
            .filter(|&i| self.powered(i))
            .count() as f64;
        vec![n * self.config.instruments.current_a; 2]
    }

    fn logic_currents(&self) -> Vec<f64> {
        vec![self.modules.len() as f64 * MODULE_CURRENT_A]
    }

    /// Acceleration along the input axis and across it [g] for instrument
    /// `i` now. On the arm (method.md (3), (13)): a = ω_i²·R(ω)/g with ω_i
    /// the rate in inertial space (the table's plus the Earth's vertical
    /// rate), R(ω) = R + k_s·ω² + R0·α·ΔT_arm + L_chamber·α·ΔT_chamber, plus the tilted axis's
    /// once-per-revolution gravity component along the radius; gravity
    /// lies across the input axis.
    pub fn input_g(&self, i: usize) -> (f64, f64) {
        let w = self.table.measured_rate_rad_s();
        let g = self.config.g_local_m_s2;
        let t = &self.config.centrifuge;
        let p = self.positions[i];
        let inertial = w + self.earth_rate_vertical_rad_s();
        let stretch_m = t.arm_stretch_m_per_rad2_s2 * w * w
            + p.drawing_radius_m * t.arm_expansion_ppm_per_c * 1e-6 * self.windage_c
            // The fixture in the chamber follows the chamber's air.
            + self.chamber.as_ref().map_or(0.0, |c| {
                c.config.radius_in_chamber_mm * 1e-3
                    * t.arm_expansion_ppm_per_c
                    * 1e-6
                    * (c.instrument_air_c - self.config.ambient_c)
            });
        // Only while the table turns: at rest the Earth's rate is no centripetal input.
        let radial = |r: f64| {
            if w == 0.0 {
                0.0
            } else {
                inertial * inertial * (r + stretch_m) / g
            }
        };
        let tilt = (t.tilt_urad * 1e-6).sin() * (self.table.angle_rad() + p.azimuth_rad).cos();
        match self.instruments[i].mounting {
            Mounting::TumbleUp => (1.0, 0.0),
            Mounting::TumbleDown => (-1.0, 0.0),
            Mounting::TumbleCrosswise { as_on_arm } => (0.0, if as_on_arm { 1.0 } else { -1.0 }),
            Mounting::ArmP => (radial(p.radius_p_m) + tilt, 1.0),
            Mounting::ArmN => (-(radial(p.radius_n_m) + tilt), 1.0),
        }
    }

    /// The structural disturbances' shift at the table's rate now [g],
    /// before each instrument's gain.
    fn disturbance_g(&self) -> f64 {
        let t = &self.config.centrifuge;
        if t.disturbances.is_empty() {
            return 0.0;
        }
        let w = self.table.measured_rate_rad_s();
        let nominal_g = w * w * t.arm_radius_m / self.config.g_local_m_s2;
        t.disturbances
            .iter()
            .map(|d| d.shift_ug(nominal_g))
            .sum::<f64>()
            * 1e-6
    }

    /// Windage heating and the low-frequency noise, one tick on.
    fn step_environment(&mut self) {
        let t = &self.config.centrifuge;
        if t.windage_c_at_100g != 0.0 {
            let w100 = (100.0 * self.config.g_local_m_s2 / t.arm_radius_m).sqrt();
            let ratio = self.table.measured_rate_rad_s().abs() / w100;
            let target = t.windage_c_at_100g * ratio * ratio * ratio;
            self.windage_c += (target - self.windage_c) * TICK_S / t.windage_tau_s;
        }
        // The low-frequency noise moves once a second (its shortest time
        // constant is ten seconds).
        if !self.tick.is_multiple_of(u64::from(TICKS_PER_SECOND)) {
            return;
        }
        let room_c = self.ambient_c();
        if let Some(chamber) = self.chamber.as_mut() {
            chamber.step(1.0, room_c);
        }
        for (state, v) in self.flicker_g.iter_mut().zip(&self.instruments) {
            if v.truth.flicker_ug == 0.0 {
                continue;
            }
            // Each process holds an equal share of the variance.
            let sigma = v.truth.flicker_ug * 1e-6 / (FLICKER_TAUS_S.len() as f64).sqrt();
            for (x, tau) in state.iter_mut().zip(FLICKER_TAUS_S) {
                let n: f64 = StandardNormal.sample(&mut self.noise_rng);
                let decay = (-1.0 / tau).exp();
                *x = *x * decay + sigma * (1.0 - decay * decay).sqrt() * n;
            }
        }
    }

    fn fire_faults(&mut self) {
        let now = self.now_s();
        let f = self.config.faults.clone();
        if let Some((m, at)) = f.module_silent
            && now >= at
            && let Some(s) = self.module_silent.get_mut(m)
        {
            *s = true;
        }
        if f.centrifuge_silent_at_s.is_some_and(|at| now >= at) {
            self.centrifuge_silent = true;
        }
        if !self.faults_fired[0] && f.interlock_open_at_s.is_some_and(|at| now >= at) {
            self.faults_fired[0] = true;
            self.table.trip_interlocks();
        }
        if !self.faults_fired[1] && f.supply_trip_at_s.is_some_and(|at| now >= at) {
            self.faults_fired[1] = true;
            self.rails.trip();
        }
        // A real over-current: the load exceeds a channel's limit.
        let currents = self.rail_currents();
        if self
            .rails
            .outputs
            .iter()
            .zip(&currents)
            .any(|(o, c)| o.on && *c > o.current_limit_a)
        {
            self.rails.trip();
        }
    }

    /// Advance one tick; returns the bytes each counter module sends in it
    /// (frames, with the configured wire faults applied).
    pub fn step(&mut self) -> Vec<Vec<u8>> {
        self.fire_faults();
        self.table.step(TICK_S, &mut self.noise_rng);
        self.step_environment();
        let now = self.now_s();
        // Power transitions and the bias random walk.
        let walk_per_tick =
            |v: &Vba| v.truth.bias_walk_ug_per_sqrt_h * 1e-6 * (TICK_S / 3600.0).sqrt();
        for i in 0..self.instruments.len() {
            let powered = self.powered(i);
            let step: f64 = StandardNormal.sample(&mut self.noise_rng);
            let v = &mut self.instruments[i];
            match (powered, v.powered_since_s) {
                (true, None) => v.powered_since_s = Some(now),
                (false, Some(_)) => v.powered_since_s = None,
                _ => {}
            }
            v.bias_walk_g += step * walk_per_tick(v);
        }

        let reference_hz = self.config.reference_hz;
        let tick_ref = (reference_hz * TICK_S).round() as u64;
        let tick_start_ref = self.tick * tick_ref;
        // The table's structural disturbance is one value per tick, for every instrument.
        let disturbance = self.disturbance_g();
        let mut out = vec![Vec::new(); self.modules.len()];
        for (m, module_out) in out.iter_mut().enumerate() {
            let alive = self.module_alive(m);
            let mut counts = [0u16; INPUTS_PER_MODULE];
            let mut recips = [spinbench_wire::fmu::ReciprocalCount::default(); INPUTS_PER_MODULE];
            for slot in 0..INSTRUMENTS_PER_MODULE {
                let i = m * INSTRUMENTS_PER_MODULE + slot;
                let (f1, f2) =
                    if self.powered(i) && !self.is(&self.config.faults.dead_instruments, i) {
                        self.frequencies(i, now, disturbance)
                    } else {
                        (0.0, 0.0)
                    };
                for (k, f) in [f1, f2].into_iter().enumerate() {
                    let input = 2 * slot + k;
                    let c = self.modules[m].inputs[input].advance(
                        f,
                        tick_start_ref,
                        tick_ref,
                        reference_hz,
                    );
                    counts[input] = u16::try_from(c.edges).unwrap_or(u16::MAX);
                    recips[input] = c.reciprocal;
                }
            }
            if !alive {
                continue;
            }
            // Temperatures once a second (frame command 2).
            let second_starts = self.tick.is_multiple_of(u64::from(TICKS_PER_SECOND));
            let temps: Vec<i16> = (0..INSTRUMENTS_PER_MODULE)
                .filter(|_| second_starts)
                .map(|slot| {
                    let t = self.instrument_temperature_c(m * INSTRUMENTS_PER_MODULE + slot);
                    (t * 100.0).round() as i16
                })
                .collect();
            let module = &mut self.modules[m];
            let mut frames = Vec::new();
            if let Some(mode) = module
                .streaming
                .filter(|_| self.tick >= module.stream_from_tick)
            {
                let message = match mode {
                    StreamMode::Gated => Message::GatedCounts {
                        seq: module.seq,
                        status: 0,
                        counts: counts.to_vec(),
                    },
                    StreamMode::Reciprocal => Message::ReciprocalCounts {
                        seq: module.seq,
                        status: 0,
                        inputs: recips.to_vec(),
                    },
                };
                module.seq = module.seq.wrapping_add(1);
                frames.push(message);
                if second_starts {
                    frames.push(Message::Temperatures {
                        seq: module.temp_seq,
                        centi_celsius: temps,
                    });
                    module.temp_seq = module.temp_seq.wrapping_add(1);
                }
            }
            for f in frames {
                self.emit(m, &f, module_out);
            }
        }
        self.tick += 1;
        out
    }

    /// The resonator frequencies of instrument `i` now, with noise;
    /// `disturbance` is the table's structural shift this tick [g].
    fn frequencies(&mut self, i: usize, now: f64, disturbance: f64) -> (f64, f64) {
        let (a, cross) = self.input_g(i);
        let pc = &self.config.instruments;
        let v = &self.instruments[i];
        let since = v.powered_since_s.map_or(0.0, |t0| (now - t0).max(0.0));
        // Relative to the warmed-up temperature at rest in the laboratory as it was at the start.
        let temp_offset =
            self.instrument_temperature_c(i) - (self.config.ambient_c + pc.self_heating_c);
        let warmup = pc.warmup_ug * 1e-6 * (-since / pc.warmup_tau_s).exp();
        // The structural disturbance is the arm's: an acceleration along the
        // radius, outward in both mountings (its gain is the fixture's coupling).
        let radial_sign = match v.mounting {
            Mounting::ArmP => 1.0,
            Mounting::ArmN => -1.0,
            Mounting::TumbleUp | Mounting::TumbleDown | Mounting::TumbleCrosswise { .. } => 0.0,
        };
        let (mut f1, mut f2) = v.resonators(&Inputs {
            a_g: a + radial_sign * disturbance * v.truth.disturbance_gain,
            cross_g: cross,
            temp_offset_c: temp_offset,
            warmup_g: warmup,
            extra_g: self.flicker_g[i].iter().sum::<f64>(),
        });
        if self.is(&self.config.faults.drifting_instruments, i) {
            let rate = match self.config.faults.drift_ug_per_s {
                r if r != 0.0 => r,
                _ => 200.0,
            };
            // dF = f1 − f2 moves by k1·(drift·t), split over the two resonators.
            let drift_hz = v.truth.k1_hz_per_g * rate * 1e-6 * now;
            f1 += drift_hz / 2.0;
            f2 -= drift_hz / 2.0;
        }
        // White frequency noise: σ per 1-s value → σ·√400 per tick, split over the two resonators.
        let mut noise_ug = v.truth.noise_ug;
        if self.is(&self.config.faults.noisy_instruments, i) {
            noise_ug *= if self.config.faults.noisy_factor > 0.0 {
                self.config.faults.noisy_factor
            } else {
                1000.0
            };
        }
        let sigma_hz = noise_ug * 1e-6 * v.truth.k1_hz_per_g * f64::from(TICKS_PER_SECOND).sqrt()
            / std::f64::consts::SQRT_2;
        let (n1, n2) = match Normal::new(0.0, sigma_hz) {
            Ok(d) => (d.sample(&mut self.noise_rng), d.sample(&mut self.noise_rng)),
            Err(_) => (0.0, 0.0),
        };
        (f1 + n1, f2 + n2)
    }

    /// Encode a message into module `m`'s output, applying wire faults.
    fn emit(&mut self, m: usize, message: &Message, out: &mut Vec<u8>) {
        let f = &self.config.faults;
        let (ber, drop_byte, drop_frame) = (f.bit_error_rate, f.byte_drop_rate, f.frame_drop_rate);
        if drop_frame > 0.0 && self.wire_rng.random::<f64>() < drop_frame {
            return;
        }
        let mut bytes = Vec::new();
        if message.encode(&mut bytes).is_err() {
            self.modules[m].overruns = self.modules[m].overruns.wrapping_add(1);
            return;
        }
        if ber > 0.0 || drop_byte > 0.0 {
            for b in bytes {
                if drop_byte > 0.0 && self.wire_rng.random::<f64>() < drop_byte {
                    continue;
                }
                let mut b = b;
                if ber > 0.0 {
                    for bit in 0..8 {
                        if self.wire_rng.random::<f64>() < ber {
                            b ^= 1 << bit;
                        }
                    }
                }
                out.push(b);
            }
        } else {
            out.extend_from_slice(&bytes);
        }
    }

    /// A frame from the station to module `m`; returns the bytes of the reply.
    pub fn handle_module_message(&mut self, m: usize, message: Result<Message, ()>) -> Vec<u8> {
        if m >= self.modules.len() || !self.module_alive(m) {
            return Vec::new();
        }
        let Ok(message) = message else {
            self.modules[m].rx_crc_errors = self.modules[m].rx_crc_errors.wrapping_add(1);
            return Vec::new();
        };
        self.addressed[m] = true;
        let cmd = message.command() as u8;
        let ack = |result| Message::Ack { cmd, result };
        let module = &mut self.modules[m];
        let reply = match message {
            Message::SetPower { mask } => {
                module.relay_mask = mask & 0x3F;
                ack(0)
            }
            Message::StartStreaming { mode } => {
                let second = u64::from(TICKS_PER_SECOND);
                module.streaming = Some(mode);
                module.stream_from_tick = self.tick.div_ceil(second) * second;
                self.has_streamed = true;
                self.lockstep_start();
                ack(0)
            }
            Message::StopStreaming => {
                module.streaming = None;
                if !self.streaming_any() {
                    self.lockstep_running = false;
                }
                ack(0)
            }
            Message::StatusRequest => Message::Status(StatusReply {
                firmware_id: FIRMWARE_ID,
                relay_mask: module.relay_mask,
                rx_crc_errors: module.rx_crc_errors,
                rx_tail_errors: 0,
                overruns: module.overruns,
            }),
            // A message only a module sends: not a command.
            _ => ack(1),
        };
        let mut out = Vec::new();
        let _ = reply.encode(&mut out);
        out
    }

    /// A line from the station to the centrifuge controller; returns the reply line.
    pub fn handle_centrifuge_line(&mut self, line: &str) -> Option<String> {
        if self.centrifuge_silent {
            return None;
        }
        match self.config.centrifuge.dialect {
            SimDialect::Acutrol => self.acutrol(line),
            SimDialect::Mnemonic => self.mnemonic(line),
        }
    }

    fn demand(&mut self, rate_deg_s: f64) -> Result<(), (i32, &'static str)> {
        if !rate_deg_s.is_finite() || rate_deg_s.abs() > self.config.centrifuge.max_rate_deg_s {
            return Err((-222, "Data out of range; rate above the table limit"));
        }
        self.table.demand_rad_s = rate_deg_s.to_radians();
        Ok(())
    }

    fn acutrol(&mut self, line: &str) -> Option<String> {
        let Ok(cmd) = parse_line(line) else {
            self.centrifuge_errors
                .push_back((-102, "Syntax error".into()));
            return None;
        };
        let is = |spec: &str| HeaderSpec::new(spec).matches(&cmd);
        let number = |i: usize| cmd.args.get(i).and_then(|a| scpi::parse_number(a).ok());
        if is(h::IDN) {
            return Some("ACUTRONIC,SPINBENCH-SIM,0,1.0".into());
        } else if is(h::STB) {
            let stb = u8::from(self.table.interlocks_closed)
                | (u8::from(self.table.rate_mode) << 1)
                | (u8::from(self.table.interlock_fault) << 2);
            return Some(stb.to_string());
        } else if is(h::READ_RATE) {
            let reply = format!("{:.6}", self.table.reported_rate_rad_s().to_degrees());
            self.lockstep_barrier();
            return Some(reply);
        } else if is(h::INTERLOCK_QUERY) {
            return Some(
                if self.table.interlocks_closed {
                    "1"
                } else {
                    "0"
                }
                .into(),
            );
        } else if is(h::SYSTEM_ERROR) {
            let (code, msg) = self
                .centrifuge_errors
                .pop_front()
                .unwrap_or((0, "No error".into()));
            return Some(format!("{code},\"{msg}\""));
        } else if is(h::DEMAND_RATE) {
            match number(1) {
                Some(r) => {
                    if let Err((code, msg)) = self.demand(r) {
                        self.centrifuge_errors.push_back((code, msg.into()));
                    }
                }
                None => self
                    .centrifuge_errors
                    .push_back((-109, "Missing parameter".into())),
            }
        } else if is(h::MODE_RATE) {
            if self.table.interlocks_closed {
                self.table.rate_mode = true;
            } else {
                self.centrifuge_errors
                    .push_back((-221, "Settings conflict; interlocks open".into()));
            }
        } else if is(h::MODE_OFF) {
            self.table.rate_mode = false;
            self.table.demand_rad_s = 0.0;
        } else if is(h::INTERLOCK_CLOSE) {
            if self.table.interlock_fault {
                self.centrifuge_errors.push_back((
                    -221,
                    "Settings conflict; interlock fault latched, reset first".into(),
                ));
            } else {
                self.table.interlocks_closed = true;
            }
        } else if is(h::INTERLOCK_OPEN) {
            self.table.interlocks_closed = false;
            self.table.rate_mode = false;
        } else if is(h::INTERLOCK_RESET) {
            self.table.interlock_fault = false;
        } else if is(h::LIMIT_RATE) || is(h::LIMIT_ACCELERATION) {
            // Accepted; the simulated table keeps its configured physical limits.
        } else {
            self.centrifuge_errors
                .push_back((-113, "Undefined header".into()));
        }
        None
    }

    fn mnemonic(&mut self, line: &str) -> Option<String> {
        let mut words = line.split_whitespace();
        let verb = words.next().unwrap_or("").to_ascii_uppercase();
        let arg = words.next();
        Some(match verb.as_str() {
            "ID?" => "SPINBENCH SIM-TABLE MNEMONIC 1.0".into(),
            "RATE?" => {
                let reply = format!(
                    "RATE {:.4}",
                    spinbench_analysis::centrifuge::rad_s_to_rpm(self.table.reported_rate_rad_s())
                );
                self.lockstep_barrier();
                reply
            }
            "ILK?" => format!("ILK {}", u8::from(self.table.interlocks_closed)),
            "ENA" if self.table.interlock_fault => "ERR interlock fault latched, send RST".into(),
            "ENA" => {
                self.table.interlocks_closed = true;
                self.table.rate_mode = true;
                "OK".into()
            }
            "DIS" => {
                self.table.interlocks_closed = false;
                "OK".into()
            }
            "RST" => {
                self.table.interlock_fault = false;
                "OK".into()
            }
            "STO" => {
                self.table.demand_rad_s = 0.0;
                "OK".into()
            }
            "JOG" => match arg.and_then(|a| a.parse::<f64>().ok()) {
                Some(rpm) => match self.demand(rpm * 6.0) {
                    Ok(()) => "OK".into(),
                    Err(_) => "ERR overspeed".into(),
                },
                None => "ERR missing rate".into(),
            },
            _ => "ERR unknown command".into(),
        })
    }

    /// A line from the station to a supply; returns the reply line.
    pub fn handle_supply_line(&mut self, which: SupplyId, line: &str) -> Option<String> {
        match which {
            SupplyId::Rails => {
                let currents = self.rail_currents();
                self.rails.handle(line, &currents)
            }
            SupplyId::Logic => {
                let currents = self.logic_currents();
                self.logic.handle(line, &currents)
            }
        }
    }
}
