//! What the station does to the bench, for the bench's tests: power and
//! stream, spin, and decode the modules' bytes with the station's own
//! decoder into one-second windows.

#![allow(dead_code)]

use spinbench_sim::world::TICK_S;
use spinbench_sim::{SimConfig, SupplyId, World};
use spinbench_wire::fmu::{
    DecoderStats, FrameDecoder, Message, StreamMode, WindowAccumulator, WindowConfig, WindowValue,
};

/// A quiet bench: no drift, ripple or warm-up, so the physics can be checked tightly.
pub fn quiet() -> SimConfig {
    let mut c = SimConfig {
        modules: 1,
        ..SimConfig::default()
    };
    c.instruments.warmup_ug = 0.0;
    c.instruments.temp_coeff_ug_per_c = 0.0;
    c.instruments.bias_walk_ug_per_sqrt_h = 0.0;
    c.centrifuge.ripple_ppm = 0.0;
    c.centrifuge.wander_ppm = 0.0;
    c
}

pub fn frame(m: &Message) -> Result<Message, ()> {
    Ok(m.clone())
}

/// Power the rails and every relay, start streaming in `mode`.
pub fn power_up(world: &mut World, mode: StreamMode) {
    for line in [
        "INST:NSEL 1",
        "VOLT 15",
        "CURR 1",
        "OUTP ON",
        "INST:NSEL 2",
        "VOLT 15",
        "CURR 1",
        "OUTP ON",
    ] {
        world.handle_supply_line(SupplyId::Rails, line);
    }
    for m in 0..world.config().modules {
        assert!(
            !world
                .handle_module_message(m, frame(&Message::SetPower { mask: 0x3F }))
                .is_empty()
        );
        assert!(
            !world
                .handle_module_message(m, frame(&Message::StartStreaming { mode }))
                .is_empty()
        );
    }
}

pub fn spin(world: &mut World, rate_deg_s: f64) {
    for line in [
        ":INTERLOCK:CLOSE 1".to_string(),
        format!(":DEMAND:RATE 1,{rate_deg_s}"),
        ":MODE:RATE 1".into(),
    ] {
        world.handle_centrifuge_line(&line);
    }
}

/// Run `seconds` and decode module `m`'s stream into one-second windows.
pub struct Capture {
    pub windows: Vec<WindowValue>,
    decoder: FrameDecoder,
    pub acc: WindowAccumulator,
    pub bytes: Vec<u8>,
    /// The temperature frames (command 2), per second: °C per slot.
    pub temps_c: Vec<Vec<f64>>,
}

impl Capture {
    pub fn new(mode: StreamMode) -> Capture {
        Capture {
            windows: Vec::new(),
            decoder: FrameDecoder::new(),
            acc: WindowAccumulator::new(WindowConfig {
                mode,
                ..WindowConfig::default()
            }),
            bytes: Vec::new(),
            temps_c: Vec::new(),
        }
    }

    pub fn run(&mut self, world: &mut World, m: usize, seconds: f64) {
        for _ in 0..(seconds / TICK_S).round() as usize {
            let out = world.step();
            self.bytes.extend(&out[m]);
            let (acc, windows, temps) = (&mut self.acc, &mut self.windows, &mut self.temps_c);
            self.decoder.decode(&out[m], |f| {
                if let Ok(msg) = Message::decode(f) {
                    if let Message::Temperatures { centi_celsius, .. } = &msg {
                        temps.push(
                            centi_celsius
                                .iter()
                                .map(|&t| f64::from(t) / 100.0)
                                .collect(),
                        );
                    }
                    windows.extend(acc.push(&msg));
                }
            });
        }
    }

    pub fn stats(&self) -> DecoderStats {
        self.decoder.stats()
    }
}

pub fn settle(world: &mut World, seconds: f64) {
    for _ in 0..(seconds / TICK_S).round() as usize {
        world.step();
    }
}
