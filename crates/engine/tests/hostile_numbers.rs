//! Every number of a plan and a station config from outside is checked
//! before anything is allocated or moved in proportion to it: a property
//! test over finite, infinite, NaN, negative and huge values that never
//! panics, never allocates without bound and never compiles an impossible
//! run; and the cases a hostile test found, each by name.

use proptest::prelude::*;
use spinbench_engine::plan::Step;
use spinbench_engine::{StationConfig, TestPlan};

fn station_text(power: &str) -> String {
    format!(
        "[arm]\nradius_m = 0.8\nmax_g = 100\n[power]\ninstrument_supply = \"rails\"\n{power}\n\
         [centrifuge]\nname = \"t\"\nmax_rate_deg_s = 2400\ntransport = {{ kind = \"tcp\", address = \"127.0.0.1:1\" }}\n\
         dialect = {{ kind = \"acutrol\" }}\n\
         [[fmu]]\nname = \"f\"\ntransport = {{ kind = \"tcp\", address = \"127.0.0.1:1\" }}\n\
         [[power_supply]]\nname = \"rails\"\nchannels = 2\ntransport = {{ kind = \"tcp\", address = \"127.0.0.1:1\" }}\n"
    )
}

fn station() -> StationConfig {
    StationConfig::from_toml(&station_text("")).expect("station")
}

/// A TOML spelling of a hostile number.
fn hostile() -> impl Strategy<Value = String> {
    prop_oneof![
        Just("inf".to_string()),
        Just("-inf".to_string()),
        Just("nan".to_string()),
        Just("-nan".to_string()),
        Just("1e300".to_string()),
        Just("-1e300".to_string()),
        Just("1e9".to_string()),
        Just("0".to_string()),
        Just("-1".to_string()),
        Just("4294967295".to_string()),
        Just("18446744073709551615".to_string()),
        (-1e12f64..1e12).prop_map(|v| format!("{v:e}")),
        (0u64..10_000).prop_map(|v| v.to_string()),
    ]
}

/// The keys of a plan whose values are numbers.
const PLAN_KEYS: [&str; 16] = [
    "range_g",
    "warmup_s",
    "order",
    "dwell.seconds",
    "dwell.sem_target_ug",
    "dwell.min_seconds",
    "dwell.max_seconds",
    "stability.rate_tolerance_ppm",
    "stability.hold_s",
    "stability.drift_limit_ug_per_s",
    "stability.max_settle_s",
    "stability.max_restarts",
    "stability.noise_limit_ug",
    "limits.k2_max_ug_per_g2",
    "limits.nonlinearity_max_ppm_fs",
    "limits.marginal_fraction",
];

fn plan_with(key: &str, value: &str) -> String {
    match key.split_once('.') {
        Some((table, k)) => format!("[{table}]\n{k} = {value}\n[serials]\n1 = \"A\"\n"),
        None => format!("{key} = {value}\n[serials]\n1 = \"A\"\n"),
    }
}

/// A compiled plan is one a station can run to its end.
fn assert_runnable(plan: &TestPlan, steps: &[Step]) {
    assert!(plan.range_g.is_finite() && plan.range_g > 0.0 && plan.range_g <= 1000.0);
    assert!(plan.warmup_s.is_finite() && (0.0..=86_400.0).contains(&plan.warmup_s));
    assert!((2..=3600).contains(&plan.dwell.seconds));
    let s = &plan.stability;
    for v in [
        s.rate_tolerance_ppm,
        s.drift_limit_ug_per_s,
        s.noise_limit_ug,
        plan.limits.k2_max_ug_per_g2,
    ] {
        assert!(v.is_finite() && v > 0.0, "{v}");
    }
    assert!((0.0..=1.0).contains(&plan.limits.marginal_fraction));
    assert!(steps.len() < 10_000, "{} steps", steps.len());
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    #[test]
    fn hostile_plan_numbers_are_refused_or_make_a_runnable_plan(
        key in prop::sample::select(PLAN_KEYS.to_vec()),
        value in hostile(),
    ) {
        let text = plan_with(key, &value);
        // Parsing and compiling never panic and never allocate in proportion
        // to the value (range_g = 1e300 would ask for 2e299 levels).
        if let Ok(plan) = TestPlan::from_toml(&text)
            && let Ok(compiled) = plan.compile(&station())
        {
            assert_runnable(&plan, &compiled.steps);
        }
    }

    #[test]
    fn hostile_levels_are_refused_or_bounded(values in prop::collection::vec(hostile(), 0..12)) {
        let text = format!("levels = [{}]\n[serials]\n1 = \"A\"\n", values.join(", "));
        if let Ok(plan) = TestPlan::from_toml(&text)
            && let Ok(compiled) = plan.compile(&station())
        {
            assert_runnable(&plan, &compiled.steps);
        }
    }

    #[test]
    fn hostile_station_numbers_are_refused_or_sane(
        key in prop::sample::select(vec![
            "rail_volts", "rail_current_limit_a", "instrument_current_a",
        ]),
        value in hostile(),
    ) {
        if let Ok(s) = StationConfig::from_toml(&station_text(&format!("{key} = {value}"))) {
            let p = &s.power;
            for v in [p.rail_volts, p.rail_current_limit_a, p.instrument_current_a] {
                prop_assert!(v.is_finite() && v > 0.0, "{key} = {value} accepted as {v}");
            }
            prop_assert!(p.rail_volts <= 60.0 && p.rail_current_limit_a <= 20.0);
        }
    }
}

/// The values a hostile test showed were accepted, each refused naming its key and bound.
#[test]
fn the_values_found_by_the_hostile_test_are_refused_naming_the_key() {
    let cases = [
        ("range_g", "inf", "range_g"),
        ("range_g", "1e9", "MAX_LEVEL_G"),
        ("dwell.seconds", "4294967295", "MAX_DWELL_S"),
        ("warmup_s", "1e300", "MAX_WARMUP_S"),
        (
            "stability.rate_tolerance_ppm",
            "nan",
            "stability.rate_tolerance_ppm",
        ),
        (
            "stability.rate_tolerance_ppm",
            "-5",
            "stability.rate_tolerance_ppm",
        ),
        (
            "stability.drift_limit_ug_per_s",
            "nan",
            "stability.drift_limit_ug_per_s",
        ),
        ("stability.noise_limit_ug", "-1", "stability.noise_limit_ug"),
        (
            "limits.nonlinearity_max_ppm_fs",
            "nan",
            "limits.nonlinearity_max_ppm_fs",
        ),
        ("limits.k2_max_ug_per_g2", "inf", "limits.k2_max_ug_per_g2"),
    ];
    for (key, value, named) in cases {
        let e = TestPlan::from_toml(&plan_with(key, value))
            .expect_err(&format!("{key} = {value}"))
            .to_string();
        assert!(e.contains(named), "{key} = {value}: {e}");
    }
    for (power, named) in [
        ("rail_volts = -1000", "power.rail_volts"),
        ("rail_current_limit_a = nan", "power.rail_current_limit_a"),
        ("rail_volts = 1e9", "MAX_RAIL_V"),
    ] {
        let e = StationConfig::from_toml(&station_text(power))
            .expect_err(power)
            .to_string();
        assert!(e.contains(named), "{power}: {e}");
    }
}

#[test]
fn station_toml_errors_give_the_line_and_column() {
    let text = station_text("").replace("max_g = 100", "max_g = \"a hundred\"");
    let e = StationConfig::from_toml(&text)
        .expect_err("bad type")
        .to_string();
    assert!(e.contains("line 3, column 9"), "{e}");
    assert!(!e.contains("bytes"), "{e}");
}

#[test]
fn a_device_deadline_beyond_its_bound_is_refused() {
    let text = station_text("").replace(
        "[[power_supply]]\nname = \"rails\"",
        "[[power_supply]]\nio = { timeout_ms = 18446744073709551615 }\nname = \"rails\"",
    );
    let e = StationConfig::from_toml(&text)
        .expect_err("deadline")
        .to_string();
    assert!(e.contains("io.timeout_ms"), "{e}");
}
