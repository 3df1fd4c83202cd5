//! One tick of the world: the table, the instruments' frequencies, the
//! counter modules' frames.

use super::{
    INPUTS_PER_MODULE, INSTRUMENTS_PER_MODULE, Inputs, Message, Mounting, Normal, StandardNormal,
    StreamMode, TICK_S, TICKS_PER_SECOND, Vba, World,
};
use rand::RngExt;
use rand_distr::Distribution;

impl World {
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
                let (f1, f2) = if self.powered(i)
                    && !self.is(&self.config.faults.dead_instruments, i)
                    && !self.fallen_silent(i)
                {
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
    pub(super) fn frequencies(&mut self, i: usize, now: f64, disturbance: f64) -> (f64, f64) {
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
    pub(super) fn emit(&mut self, m: usize, message: &Message, out: &mut Vec<u8>) {
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
}
