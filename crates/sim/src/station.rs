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
use std::io::IsTerminal;

/// A complete station config (TOML) for the bench: its arm, the power roles
/// and its device sections; `power_extra` adds lines to `[power]`.
pub fn station_toml(bench: &RunningBench, power_extra: &str) -> String {
    let (r0, instruments, current_a, latitude_deg, uncertainty) = bench.with_world(|w| {
        let c = w.config();
        (
            c.centrifuge.arm_radius_m,
            c.modules * INSTRUMENTS_PER_MODULE,
            c.instruments.current_a,
            c.latitude_deg,
            uncertainty_toml(c),
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
        "station = \"spinbench virtual bench\"\nsimulated = true\n\n[arm]\nradius_m = {r0}\nmax_g = 100\n{latitude}\n[power]\ninstrument_supply = \"rails\"\nmodule_supply = \"logic\"\n{limit}{power_extra}\n{uncertainty}{}",
        bench.station_config_toml()
    )
}

/// The `[uncertainty]` section a station on this bench would carry: what
/// its equipment's specifications say (the controller's read-back accuracy
/// and resolution, the timebase, the instruments' and the arm's temperature
/// coefficients, the windage heating and the radius found through a 1 g
/// reading that gravity across the axis shifts), as bounds the bench's
/// errors lie within. The station is not told the errors themselves.
fn uncertainty_toml(c: &crate::config::SimConfig) -> String {
    let t = &c.centrifuge;
    let p = &c.instruments;
    if t.readback_scale_ppm == 0.0 && t.windage_c_at_100g == 0.0 && p.cross_axis_max_ug_per_g == 0.0
    {
        return String::new();
    }
    // The 1 g radius reading: gravity across the axis shifts it by up to the
    // cross-axis coefficient (the budget's rectangular `cross_axis`, unless a
    // four-position tumble measures it); the readings' noise the station
    // measures itself; the bench's drawing-to-true radius is what the step finds.
    format!(
        "[uncertainty]\ncross_axis_ug_per_g = {}\nrate_accuracy_ppm = {}\nrate_resolution_deg_s = {}\ntimebase_ppm = 0.1\ntemperature_rise_c_at_100g = {}\nk0_tempco_ug_per_c = {}\nk1_tempco_ppm_per_c = {}\narm_expansion_ppm_per_c = {}\n{}\n",
        p.cross_axis_max_ug_per_g,
        t.readback_scale_ppm.abs().max(1.0),
        t.readback_resolution_deg_s,
        t.windage_c_at_100g,
        p.temp_coeff_ug_per_c,
        p.k1_temp_coeff_ppm_per_c,
        t.arm_expansion_ppm_per_c,
        chamber_radius_line(c),
    ) + &table_disturbance_lines(c)
}

/// The table's characterization as `[uncertainty]` lines: the broad
/// structural disturbances of its acceleration (half-width 4 g or more; a
/// sharper one shows as a level off the curve) bounded by the sum of their
/// heights, with the narrowest one's half-width; nothing for a table without
/// them. A real station takes these from its centrifuge's acceptance test.
fn table_disturbance_lines(c: &crate::config::SimConfig) -> String {
    let broad: Vec<_> = c
        .centrifuge
        .disturbances
        .iter()
        .filter(|d| d.width_g >= 4.0)
        .collect();
    if broad.is_empty() {
        return String::new();
    }
    let height: f64 = broad.iter().map(|d| d.amplitude_ug.abs()).sum();
    let width = broad
        .iter()
        .map(|d| d.width_g)
        .fold(f64::INFINITY, f64::min);
    format!("table_disturbance_ug = {height}\ntable_disturbance_width_g = {width}\n")
}

/// The chamber's share of the radius as a bound on its expansion, a line of
/// `[uncertainty]` (the station's drawing of the fixture: the length in the
/// chamber times the arm's coefficient, over the arm's radius), or nothing
/// without a chamber.
fn chamber_radius_line(c: &crate::config::SimConfig) -> String {
    let t = &c.centrifuge;
    match &c.chamber {
        Some(ch) if t.arm_radius_m > 0.0 => format!(
            "chamber_radius_expansion_ppm_per_c = {}\n",
            ch.radius_in_chamber_mm * 1e-3 * t.arm_expansion_ppm_per_c / t.arm_radius_m
        ),
        _ => String::new(),
    }
}

/// The simulator's mounting for a requested fixture.
pub fn mounting(fixture: Fixture) -> Mounting {
    match fixture {
        Fixture::Up => Mounting::TumbleUp,
        Fixture::Down => Mounting::TumbleDown,
        Fixture::Arm(Mount::P) => Mounting::ArmP,
        Fixture::Arm(Mount::N) => Mounting::ArmN,
        Fixture::Crosswise { as_on_arm } => Mounting::TumbleCrosswise { as_on_arm },
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
            // On a terminal the prompt replaces the progress line; into a
            // file or pipe it is a line of its own (a log holds no escape codes).
            let clear = if std::io::stderr().is_terminal() {
                "\r\x1b[2K"
            } else {
                ""
            };
            eprintln!(
                "{clear}  operator prompt: {text}\n    → answered automatically: the simulator remounted the instruments"
            );
        }
        Answer {
            proceed: true,
            by: "simulator (automatic operator)".into(),
        }
    }
}
