//! What the bench knows and the station must find out: the truth types,
//! and the perfect-fit truths of each instrument on this centrifuge.

use super::{EARTH_RATE_RAD_S, INSTRUMENTS_PER_MODULE, Inputs, Serialize, VbaTruth, World};

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

impl World {
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
}
