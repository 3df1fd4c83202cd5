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

mod commands;
mod environment;
mod tick;
mod truth;

pub use truth::{CentrifugeTruth, InstrumentTruth, PerMountingK2, Position, Truth};

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
    /// How long the table has turned in all [s].
    spun_s: f64,
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
            spun_s: 0.0,
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
}
