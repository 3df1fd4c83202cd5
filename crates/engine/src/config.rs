//! The station config (TOML): the devices (`[centrifuge]`, `[[fmu]]`,
//! `[[power_supply]]` as the `devices` crate defines them), which supply
//! feeds what, the arm, and local gravity. Errors name the key.

use crate::bench::Bench;
use serde::Deserialize;
use spinbench_devices::PowerSupply;
use spinbench_devices::capture::RawCapture;

/// The raw capture file of counter module `index` (0-based) in a run's `raw` directory.
pub fn raw_capture_file(index: usize) -> String {
    format!("fmu-{}.gz", index + 1)
}
use spinbench_devices::config::{CentrifugeConfig, ConnectError, FmuConfig, PowerSupplyConfig};

/// Line and column (1-based) of byte `offset` in `text`.
pub fn line_column(text: &str, offset: usize) -> (usize, usize) {
    let before = text.get(..offset.min(text.len())).unwrap_or(text);
    let line = before.matches('\n').count() + 1;
    let column = before
        .rsplit('\n')
        .next()
        .map_or(1, |l| l.chars().count() + 1);
    (line, column)
}

/// The whole station.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StationConfig {
    /// Station name, recorded with every run.
    #[serde(default = "default_station_name")]
    pub station: String,
    /// Local gravity [m/s²] (default 9.80665).
    #[serde(default = "default_g")]
    pub g_local_m_s2: f64,
    /// The arm and its fixture positions.
    pub arm: ArmConfig,
    /// Which supply outputs feed the instruments and the modules.
    pub power: PowerConfig,
    /// The centrifuge controller.
    pub centrifuge: CentrifugeConfig,
    /// The counter modules, in slot order (module i holds instruments 6i..6i+5).
    pub fmu: Vec<FmuConfig>,
    /// The programmable supplies.
    pub power_supply: Vec<PowerSupplyConfig>,
    /// The Type B inputs of every instrument's GUM uncertainty budget
    /// (method.md §6): the controller's read-back accuracy and resolution,
    /// g_local, the counters' timebase, the arm-stretch coefficient's
    /// uncertainty, the radius and the temperature. Absent: Type A only.
    #[serde(default)]
    pub uncertainty: spinbench_analysis::uncertainty::TypeBInputs,
    /// The instruments' temperature limit. Absent: not checked.
    #[serde(default)]
    pub temperature: TemperatureLimits,
    /// The temperature chamber, if the station has one.
    #[serde(default)]
    pub chamber: Option<spinbench_devices::chamber::ChamberConfig>,
    /// How the equipment register holds runs back.
    #[serde(default)]
    pub equipment: EquipmentPolicy,
    /// True in the config of the virtual bench, as spinbench writes it
    /// (not by hand): a run recorded with it is continued only on the
    /// virtual bench, and a run on hardware never is.
    #[serde(default)]
    pub simulated: bool,
    /// The station's time zone, a fixed offset (`"UTC+08:00"`; default
    /// UTC): its pages and run reports show times in it, the zone said.
    #[serde(default)]
    pub time_zone: crate::time_zone::UtcOffset,
}

/// `[equipment]`: what the equipment register asks before a run starts.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EquipmentPolicy {
    /// A device of the station that is not in the register holds a new run
    /// back like an overdue one (an admin may override, with a reason).
    /// Default false: a station that keeps no register still runs (issue
    /// 27 item 23).
    #[serde(default)]
    pub require_registered: bool,
}

/// `[temperature]`: what the station does with the instruments' temperatures.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TemperatureLimits {
    /// An instrument that reports more than this [°C] stops the run (into
    /// the safe state, the instrument and its temperature recorded).
    pub instrument_max_c: Option<f64>,
    /// Where the chamber goes in the safe state, with the purge on [°C]
    /// (default 23, the laboratory).
    #[serde(default = "default_ambient_c")]
    pub ambient_c: f64,
    /// The laboratory air's dew point [°C] (default 10): the dry-air purge
    /// goes on before the chamber is set below it (plus 2 °C) and stays on
    /// until the chamber is warm again.
    #[serde(default = "default_dew_point_c")]
    pub dew_point_c: f64,
}

fn default_dew_point_c() -> f64 {
    10.0
}

fn default_ambient_c() -> f64 {
    23.0
}

impl Default for TemperatureLimits {
    fn default() -> Self {
        TemperatureLimits {
            instrument_max_c: None,
            ambient_c: default_ambient_c(),
            dew_point_c: default_dew_point_c(),
        }
    }
}

fn default_station_name() -> String {
    "spinbench".into()
}

fn default_g() -> f64 {
    spinbench_analysis::STANDARD_GRAVITY_M_S2
}

/// The arm.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ArmConfig {
    /// Drawing radius R0 of every fixture position [m].
    pub radius_m: f64,
    /// Per-position drawing radii [m], overriding `radius_m` (index = module·6 + slot).
    #[serde(default)]
    pub position_radius_m: Vec<f64>,
    /// The largest acceleration the fixtures are rated for [g].
    pub max_g: f64,
    /// Latitude of the station [degrees, north positive]: the Earth's
    /// vertical rate Ω_E·sin(latitude) is added to the table's rate (positive
    /// counter-clockwise seen from above) for the applied acceleration
    /// (method.md §5). Absent: no Earth-rate correction.
    #[serde(default)]
    pub latitude_deg: Option<f64>,
    /// Arm stretch c [µg/g²] (method.md (13), c = k_s·g/R0²): the radius
    /// grows as R(ω) = R·(1 + c·a) with the acceleration a at R0, and every
    /// applied acceleration includes it. Its uncertainty is
    /// `uncertainty.arm_stretch_u_ug_per_g2`. Default 0.
    #[serde(default)]
    pub stretch_ug_per_g2: f64,
    /// The table's signature learned from past runs is used only while the
    /// `[arm]` and `[centrifuge]` sections stay as they were; raise this
    /// number to forget it without another change (after a repair of the
    /// table, say). Default 0.
    #[serde(default)]
    pub signature_epoch: u32,
}

/// Supply roles.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PowerConfig {
    /// Name of the supply feeding the instruments' ±15 V rails (two outputs).
    pub instrument_supply: String,
    /// Rail voltage [V] (default 15).
    #[serde(default = "default_rail_v")]
    pub rail_volts: f64,
    /// Current limit of each rail [A] (default 0.5).
    #[serde(default = "default_rail_a")]
    pub rail_current_limit_a: f64,
    /// Expected current per powered instrument [A], for the alive check (default 0.04).
    #[serde(default = "default_instrument_a")]
    pub instrument_current_a: f64,
    /// Name of the supply feeding the counter modules (+5 V), if switched by the station.
    pub module_supply: Option<String>,
}

fn default_rail_v() -> f64 {
    15.0
}

fn default_rail_a() -> f64 {
    0.5
}

fn default_instrument_a() -> f64 {
    0.04
}

/// The largest arm stretch accepted [µg/g²] (a real arm stretches a few).
pub const MAX_STRETCH_UG_PER_G2: f64 = 1000.0;

/// A station config that cannot work; names the key.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("station config: {key}: {problem}")]
pub struct StationConfigError {
    /// The key.
    pub key: String,
    /// What is wrong and what to do.
    pub problem: String,
}

impl StationConfig {
    /// Parse and validate TOML text.
    pub fn from_toml(text: &str) -> Result<StationConfig, StationConfigError> {
        let config: StationConfig = toml::from_str(text).map_err(|e| StationConfigError {
            key: e.span().map_or_else(
                || "(file)".into(),
                |s| {
                    let (line, column) = line_column(text, s.start);
                    format!("line {line}, column {column}")
                },
            ),
            problem: e.message().to_string(),
        })?;
        config.validate()?;
        Ok(config)
    }

    /// Number of instrument slots (6 per module).
    pub fn slots(&self) -> usize {
        self.fmu.len() * spinbench_wire::fmu::INSTRUMENTS_PER_MODULE
    }

    /// The vertical component of the Earth's rate at the station [rad/s]
    /// (0 when the latitude is not configured).
    pub fn earth_rate_vertical_rad_s(&self) -> f64 {
        self.arm.latitude_deg.map_or(0.0, |lat| {
            spinbench_analysis::centrifuge::EARTH_RATE_RAD_S * lat.to_radians().sin()
        })
    }

    /// The table's rate in inertial space for a read-back rate [rad/s]: the
    /// Earth's vertical rate added (method.md §5).
    pub fn inertial_rate_rad_s(&self, table_rad_s: f64) -> f64 {
        if table_rad_s == 0.0 {
            0.0
        } else {
            table_rad_s + self.earth_rate_vertical_rad_s()
        }
    }

    /// The radius at rate ω relative to the radius at 1 g: the arm stretch
    /// 1 + c·(a − 1) with a = ω²·R0/g (method.md (13)). The radius step
    /// finds each instrument's radius at 1 g, so only the stretch beyond it counts.
    pub fn stretch_factor(&self, rate_rad_s: f64) -> f64 {
        let a = rate_rad_s * rate_rad_s * self.arm.radius_m / self.g_local_m_s2;
        1.0 + self.arm.stretch_ug_per_g2 * 1e-6 * (a - 1.0)
    }

    /// The Type B inputs of slot `i`'s budget: the configured ones with the
    /// slot's radius and g_local.
    pub fn type_b(&self, i: usize) -> spinbench_analysis::uncertainty::TypeBInputs {
        spinbench_analysis::uncertainty::TypeBInputs {
            arm_radius_m: self.drawing_radius_m(i),
            g_local_m_s2: self.g_local_m_s2,
            ..self.uncertainty
        }
    }

    /// Drawing radius of slot `i` [m].
    pub fn drawing_radius_m(&self, i: usize) -> f64 {
        self.arm
            .position_radius_m
            .get(i)
            .copied()
            .unwrap_or(self.arm.radius_m)
    }

    /// Open every device of the station through the production drivers.
    pub fn connect(&self) -> Result<Bench, ConnectError> {
        self.connect_capturing(None)
    }

    /// As [`StationConfig::connect`], keeping the raw bytes of counter module
    /// i in `raw_dir/fmu-<i+1>.gz` (appended; see `spinbench_devices::capture`).
    pub fn connect_capturing(
        &self,
        raw_dir: Option<&std::path::Path>,
    ) -> Result<Bench, ConnectError> {
        let centrifuge = self.centrifuge.connect()?;
        let modules = self
            .fmu
            .iter()
            .enumerate()
            .map(|(i, f)| {
                let capture = match raw_dir {
                    Some(dir) => {
                        let path = dir.join(raw_capture_file(i));
                        Some(
                            RawCapture::new_segment(&path).map_err(|e| ConnectError::Open {
                                device: f.name.clone(),
                                error: format!(
                                    "cannot open the raw capture {}: {e}",
                                    path.display()
                                ),
                            })?,
                        )
                    }
                    None => None,
                };
                f.connect_capturing(i, capture)
            })
            .collect::<Result<Vec<_>, _>>()?;
        let supply = |name: &str| -> Result<Box<dyn PowerSupply>, ConnectError> {
            match self.power_supply.iter().find(|p| p.name == name) {
                Some(p) => p.connect(),
                None => Err(spinbench_devices::config::ConfigError {
                    key: "power".into(),
                    problem: format!("no [[power_supply]] named '{name}'"),
                }
                .into()),
            }
        };
        Ok(Bench {
            centrifuge,
            modules,
            instrument_supply: supply(&self.power.instrument_supply)?,
            module_supply: self
                .power
                .module_supply
                .as_deref()
                .map(supply)
                .transpose()?,
            chamber: self.chamber.as_ref().map(|c| c.connect()).transpose()?,
        })
    }

    /// The roles of the station's devices, as a run's device list names
    /// them (`centrifuge`, `fmu 1` …, `instrument supply`, `module supply`):
    /// the keys of the equipment register.
    pub fn device_roles(&self) -> Vec<String> {
        let mut roles = vec!["centrifuge".to_string()];
        roles.extend((1..=self.fmu.len()).map(|m| format!("fmu {m}")));
        roles.push("instrument supply".into());
        if self.power.module_supply.is_some() {
            roles.push("module supply".into());
        }
        roles
    }

    /// Check every value that can be checked without the hardware.
    pub fn validate(&self) -> Result<(), StationConfigError> {
        let err = |key: &str, problem: String| {
            Err(StationConfigError {
                key: key.into(),
                problem,
            })
        };
        use crate::bounds::*;
        if self.station.chars().count() > MAX_NAME_CHARS {
            return err(
                "station",
                format!(
                    "'{}': at most {MAX_NAME_CHARS} characters",
                    shown(&self.station)
                ),
            );
        }
        // A name with a right-to-left override or a zero-width character
        // would let one station look like another.
        match person_text(&self.station) {
            Ok(name) if name.is_empty() => {
                return err("station", "empty: give the station a name".into());
            }
            Ok(_) => {}
            Err(why) => return err("station", why.to_string()),
        }
        check_positive(self.arm.radius_m, MAX_ARM_RADIUS_M, "m", "MAX_ARM_RADIUS_M")
            .map_err(at("arm.radius_m"))?;
        check_positive(self.arm.max_g, MAX_ARM_G, "g", "MAX_ARM_G").map_err(at("arm.max_g"))?;
        if let Some(lat) = self.arm.latitude_deg
            && !(lat.is_finite() && (-90.0..=90.0).contains(&lat))
        {
            return Err(at("arm.latitude_deg")(format!(
                "{lat} is not a latitude from -90 to 90 degrees"
            )));
        }
        if self.fmu.len() > MAX_MODULES {
            return err(
                "fmu",
                format!(
                    "{} modules; at most {MAX_MODULES} (MAX_MODULES)",
                    self.fmu.len()
                ),
            );
        }
        if self.arm.position_radius_m.len() > self.slots() {
            return err(
                "arm.position_radius_m",
                format!(
                    "{} radii for {} slots",
                    self.arm.position_radius_m.len(),
                    self.slots()
                ),
            );
        }
        check_positive(self.power.rail_volts, MAX_RAIL_V, "V", "MAX_RAIL_V")
            .map_err(at("power.rail_volts"))?;
        check_positive(
            self.power.rail_current_limit_a,
            MAX_RAIL_A,
            "A",
            "MAX_RAIL_A",
        )
        .map_err(at("power.rail_current_limit_a"))?;
        check_positive(
            self.power.instrument_current_a,
            MAX_INSTRUMENT_A,
            "A",
            "MAX_INSTRUMENT_A",
        )
        .map_err(at("power.instrument_current_a"))?;
        if !(self.g_local_m_s2 > 9.7 && self.g_local_m_s2 < 9.9) {
            return err(
                "g_local_m_s2",
                format!(
                    "{} m/s² is not a gravity on Earth (expected 9.7 to 9.9; 9.78 at the equator to 9.84 at the poles)",
                    self.g_local_m_s2
                ),
            );
        }
        if !(self.arm.radius_m > 0.0 && self.arm.radius_m.is_finite()) {
            return err("arm.radius_m", "must be a positive length in metres".into());
        }
        if let Some((i, r)) = self
            .arm
            .position_radius_m
            .iter()
            .enumerate()
            .find(|(_, r)| !(**r > 0.0 && r.is_finite()))
        {
            return err(
                &format!("arm.position_radius_m[{i}]"),
                format!("{r} is not a positive length in metres"),
            );
        }
        if !(self.arm.stretch_ug_per_g2.is_finite()
            && self.arm.stretch_ug_per_g2.abs() <= MAX_STRETCH_UG_PER_G2)
        {
            return err(
                "arm.stretch_ug_per_g2",
                format!(
                    "{} is not an arm stretch from -{MAX_STRETCH_UG_PER_G2} to {MAX_STRETCH_UG_PER_G2} µg/g² (MAX_STRETCH_UG_PER_G2)",
                    self.arm.stretch_ug_per_g2
                ),
            );
        }
        if let Some(chamber) = &self.chamber {
            chamber.validate().map_err(|e| StationConfigError {
                key: e.key,
                problem: e.problem,
            })?;
        }
        let (lo, hi) = crate::bounds::INSTRUMENT_TEMPERATURE_RANGE_C;
        for (key, t) in [
            ("temperature.ambient_c", self.temperature.ambient_c),
            ("temperature.dew_point_c", self.temperature.dew_point_c),
        ] {
            if !(t.is_finite() && (lo..=hi).contains(&t)) {
                return err(
                    key,
                    format!("{t} is not a temperature from {lo} to {hi} °C"),
                );
            }
        }
        if let Some(t) = self.temperature.instrument_max_c {
            let (lo, hi) = crate::bounds::INSTRUMENT_TEMPERATURE_RANGE_C;
            if !(t.is_finite() && (lo..=hi).contains(&t)) {
                return err(
                    "temperature.instrument_max_c",
                    format!(
                        "{t} is not an instrument temperature from {lo} to {hi} °C (INSTRUMENT_TEMPERATURE_RANGE_C)"
                    ),
                );
            }
        }
        if let Err(problem) = self.type_b(0).validate() {
            return err("uncertainty", problem.to_string());
        }
        if self.uncertainty.radius_reading_ppm_p != 0.0
            || self.uncertainty.radius_reading_ppm_n != 0.0
        {
            return err(
                "uncertainty.radius_reading_ppm_p",
                "the radius's reading noise is measured per instrument by the station; \
                 give the fixture's part as radius_ppm"
                    .into(),
            );
        }
        if !(self.arm.max_g > 0.0 && self.arm.max_g.is_finite()) {
            return err("arm.max_g", "must be a positive acceleration in g".into());
        }
        if self.fmu.is_empty() {
            return err(
                "fmu",
                "at least one counter module ([[fmu]]) is needed".into(),
            );
        }
        self.centrifuge.validate().map_err(|e| StationConfigError {
            key: e.key,
            problem: e.problem,
        })?;
        for (i, f) in self.fmu.iter().enumerate() {
            f.validate(i).map_err(|e| StationConfigError {
                key: e.key,
                problem: e.problem,
            })?;
            // A module's name is how every message and the device list
            // name it: two of one name would make them ambiguous.
            if let Some(first) = self.fmu[..i].iter().position(|o| o.name == f.name) {
                return err(
                    &format!("fmu[{i}].name"),
                    format!(
                        "'{}' is the name of fmu[{first}] too; give each counter module its own name",
                        f.name
                    ),
                );
            }
        }
        for (i, p) in self.power_supply.iter().enumerate() {
            if let Some(first) = self.power_supply[..i].iter().position(|o| o.name == p.name) {
                return err(
                    &format!("power_supply[{i}].name"),
                    format!(
                        "'{}' is the name of power_supply[{first}] too; give each supply its own name",
                        p.name
                    ),
                );
            }
        }
        for (i, p) in self.power_supply.iter().enumerate() {
            p.validate(i).map_err(|e| StationConfigError {
                key: e.key,
                problem: e.problem,
            })?;
        }
        let names: Vec<&str> = self.power_supply.iter().map(|p| p.name.as_str()).collect();
        if !names.contains(&self.power.instrument_supply.as_str()) {
            return err(
                "power.instrument_supply",
                format!(
                    "no [[power_supply]] named '{}' (have: {})",
                    self.power.instrument_supply,
                    names.join(", ")
                ),
            );
        }
        if let Some(m) = &self.power.module_supply
            && !names.contains(&m.as_str())
        {
            return err(
                "power.module_supply",
                format!(
                    "no [[power_supply]] named '{m}' (have: {})",
                    names.join(", ")
                ),
            );
        }
        let draw_a = self.slots() as f64 * self.power.instrument_current_a;
        if self.power.rail_current_limit_a < draw_a {
            return err(
                "power.rail_current_limit_a",
                format!(
                    "{} A is below what {} instruments draw ({draw_a:.2} A at power.instrument_current_a = {} A): the supply would trip at power-on",
                    self.power.rail_current_limit_a,
                    self.slots(),
                    self.power.instrument_current_a
                ),
            );
        }
        Ok(())
    }
}

/// A problem (a bound's refusal, or a sentence) at the station config's key `key`.
fn at<P: std::fmt::Display>(key: &str) -> impl FnOnce(P) -> StationConfigError {
    let key = key.to_string();
    move |problem: P| StationConfigError {
        key,
        problem: problem.to_string(),
    }
}
