//! The virtual bench as a station: the station sections that go with its
//! devices (currents and slot counts from the bench's own config), and the
//! operator whose hands are the simulator's. The engine does not know the
//! simulator; the simulator plays a station to it.

use crate::Mounting;
use crate::serve::RunningBench;
use spinbench_analysis::Mount;
use spinbench_engine::plan::Fixture;
use spinbench_engine::{Answer, Operator};
use spinbench_wire::fmu::INSTRUMENTS_PER_MODULE;

/// A complete station config (TOML) for the bench: its arm, the power roles
/// and its device sections; `power_extra` adds lines to `[power]`.
pub fn station_toml(bench: &RunningBench, power_extra: &str) -> String {
    let (r0, instruments, current_a, latitude_deg) = bench.with_world(|w| {
        let c = w.config();
        (
            c.centrifuge.arm_radius_m,
            c.modules * INSTRUMENTS_PER_MODULE,
            c.instruments.current_a,
            c.latitude_deg,
        )
    });
    // The station knows where it stands: the bench's latitude, for the Earth-rate correction.
    let latitude = if latitude_deg == 0.0 {
        String::new()
    } else {
        format!("latitude_deg = {latitude_deg}\n")
    };
    // The rails' limit: the default 0.5 A, or a quarter above what a bigger bench draws.
    let mut limit = if power_extra.contains("rail_current_limit_a") {
        String::new()
    } else {
        let draw_a = instruments as f64 * current_a;
        format!(
            "rail_current_limit_a = {}\n",
            ((draw_a * 1.25 * 10.0).ceil() / 10.0).max(0.5)
        )
    };
    if !power_extra.contains("instrument_current_a") {
        limit.push_str(&format!("instrument_current_a = {current_a}\n"));
    }
    format!(
        "station = \"spinbench virtual bench\"\n\n[arm]\nradius_m = {r0}\nmax_g = 100\n{latitude}\n[power]\ninstrument_supply = \"rails\"\nmodule_supply = \"logic\"\n{limit}{power_extra}\n{}",
        bench.station_config_toml()
    )
}

/// The simulator's mounting for a requested fixture.
pub fn mounting(fixture: Fixture) -> Mounting {
    match fixture {
        Fixture::Up => Mounting::TumbleUp,
        Fixture::Down => Mounting::TumbleDown,
        Fixture::Arm(Mount::P) => Mounting::ArmP,
        Fixture::Arm(Mount::N) => Mounting::ArmN,
    }
}

/// Answers every prompt by remounting the instruments in the simulator.
pub struct SimOperator<'a> {
    bench: &'a RunningBench,
    quiet: bool,
}

impl<'a> SimOperator<'a> {
    /// An operator for `bench`; unless `quiet`, each prompt is shown with its automatic answer.
    pub fn new(bench: &'a RunningBench, quiet: bool) -> Self {
        SimOperator { bench, quiet }
    }
}

impl Operator for SimOperator<'_> {
    fn ask(&mut self, text: &str, fixtures: &[Option<Fixture>]) -> Answer {
        self.bench.with_world(|w| {
            for (i, f) in fixtures.iter().enumerate() {
                if let Some(f) = f {
                    w.set_mounting(i, mounting(*f));
                }
            }
        });
        if !self.quiet {
            eprintln!(
                "\r\x1b[2K  operator prompt: {text}\n    → answered automatically: the simulator remounted the instruments"
            );
        }
        Answer {
            proceed: true,
            by: "simulator (automatic operator)".into(),
        }
    }
}
