use super::*;

#[test]
fn an_exclusion_needs_a_reason_a_level_of_the_plan_and_a_known_serial() {
    let station = station(1);
    let plan = |exclusion: &str| {
        TestPlan::from_toml(&format!(
            "range_g = 30\n[serials]\n1 = \"P:A\"\n[[exclusions]]\n{exclusion}\n"
        ))
        .expect("plan")
        .compile(&station)
    };
    assert!(plan("mount = \"P\"\ng = 5\nreason = \"resonance\"").is_ok());
    assert!(plan("serial = \"A\"\nmount = \"P\"\ng = 5\nreason = \"resonance\"").is_ok());
    let e = plan("mount = \"P\"\ng = 5\nreason = \" \"").expect_err("no reason");
    assert_eq!(e.key, "exclusions[0]");
    let e = plan("mount = \"P\"\ng = 7\nreason = \"r\"").expect_err("not a level");
    assert!(e.problem.contains("not one of the plan's levels"), "{e}");
    let e = plan("serial = \"Z\"\nmount = \"P\"\ng = 5\nreason = \"r\"").expect_err("serial");
    assert!(e.problem.contains("no instrument 'Z'"), "{e}");
    // The reason rules of any text from outside: no control or invisible
    // characters, at most MAX_EXCLUSION_REASON_CHARS.
    for bad in ["res\\u202Enance", "res\\u0007onance"] {
        let e = plan(&format!("mount = \"P\"\ng = 5\nreason = \"{bad}\""))
            .expect_err("not a plain text");
        assert_eq!(e.key, "exclusions[0].reason", "{bad:?}: {e}");
    }
    let long = "x".repeat(MAX_EXCLUSION_REASON_CHARS + 1);
    let e = plan(&format!("mount = \"P\"\ng = 5\nreason = \"{long}\"")).expect_err("long");
    assert_eq!(e.key, "exclusions[0].reason");
}

#[test]
fn the_decision_rules_at_their_boundaries() {
    use DecisionRule::{Guarded, Simple};
    let (limit, band) = (20.0, 0.9);
    let g = |v: f64, u: f64| Guarded.decide(v, Some(u), limit, band);
    // Guarded: pass only with the whole interval inside.
    assert_eq!(g(17.0, 3.0), Verdict::Marginal); // 20.0 ≤ 20: inside, in the band
    assert_eq!(g(17.0, 3.000_001), Verdict::Inconclusive);
    assert_eq!(g(14.0, 3.0), Verdict::Pass); // 17 ≤ 18 = 0.9 × 20
    assert_eq!(g(15.0, 3.000_001), Verdict::Marginal);
    // Fail only with the whole interval beyond.
    assert_eq!(g(23.0, 3.0), Verdict::Inconclusive); // 20.0 is not beyond 20
    assert_eq!(g(23.000_001, 3.0), Verdict::Fail);
    // The web UI's case: 12.6 ± 19.3 against 20 is not a pass.
    assert_eq!(g(12.6, 19.3), Verdict::Inconclusive);
    assert_eq!(g(-25.0, 1.0), Verdict::Fail);
    // Guarded with no uncertainty cannot decide.
    assert_eq!(
        Guarded.decide(1.0, None, limit, band),
        Verdict::Inconclusive
    );
    assert_eq!(
        Guarded.decide(1.0, Some(f64::NAN), limit, band),
        Verdict::Inconclusive
    );
    // Simple: the value alone.
    let s = |v: f64| Simple.decide(v, Some(19.3), limit, band);
    assert_eq!(s(12.6), Verdict::Pass);
    assert_eq!(s(18.0), Verdict::Pass);
    assert_eq!(s(18.000_001), Verdict::Marginal);
    assert_eq!(s(20.0), Verdict::Marginal);
    assert_eq!(s(20.000_001), Verdict::Fail);
    // The default is guarded, and a plan can say so either way.
    assert_eq!(Limits::default().decision_rule, Guarded);
    let plan = TestPlan::from_toml("[serials]\n1 = \"A\"\n[limits]\ndecision_rule = \"simple\"\n")
        .expect("plan");
    assert_eq!(plan.limits.decision_rule, Simple);
}

#[test]
fn a_value_that_is_not_a_number_never_passes() {
    for rule in [DecisionRule::Guarded, DecisionRule::Simple] {
        for v in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            assert_eq!(
                rule.decide(v, Some(0.1), 20.0, 0.9),
                Verdict::Inconclusive,
                "{rule:?} {v}"
            );
        }
        assert_eq!(
            rule.decide(1.0, Some(0.1), f64::NAN, 0.9),
            Verdict::Inconclusive
        );
    }
}

#[test]
fn guarded_k2_max_needs_every_mounting_inside_the_limit() {
    use DecisionRule::Guarded;
    // Case: P alone straddles the limit (15.99 + 5.39 > 20),
    // while the larger |k2| (N) is well inside: inconclusive, decided by P.
    let both = [(15.99, Some(5.39)), (-17.49, Some(0.10))];
    assert_eq!(
        Guarded.decide_all(&both, 20.0, 0.9),
        (Verdict::Inconclusive, Some(0))
    );
    // Every mounting inside with its U: the larger |k2| decides (marginal here).
    let inside = [(10.0, Some(1.0)), (-18.5, Some(1.0))];
    assert_eq!(
        Guarded.decide_all(&inside, 20.0, 0.9),
        (Verdict::Marginal, Some(1))
    );
    // Any mounting beyond with its U: fail.
    let beyond = [(25.0, Some(1.0)), (-1.0, Some(30.0))];
    assert_eq!(
        Guarded.decide_all(&beyond, 20.0, 0.9),
        (Verdict::Fail, Some(0))
    );
    assert_eq!(
        Guarded.decide_all(&[], 20.0, 0.9),
        (Verdict::Inconclusive, None)
    );
}

fn station(slots_modules: usize) -> StationConfig {
    let fmu: String = (0..slots_modules)
        .map(|i| format!("[[fmu]]\nname = \"f{i}\"\ntransport = {{ kind = \"tcp\", address = \"127.0.0.1:1\" }}\n"))
        .collect();
    StationConfig::from_toml(&format!(
        "[arm]\nradius_m = 0.8\nmax_g = 100\n[power]\ninstrument_supply = \"rails\"\n\
         [centrifuge]\nname = \"t\"\nmax_rate_deg_s = 2400\ntransport = {{ kind = \"tcp\", address = \"127.0.0.1:1\" }}\n\
         dialect = {{ kind = \"acutrol\" }}\n{fmu}\
         [[power_supply]]\nname = \"rails\"\nchannels = 2\ntransport = {{ kind = \"tcp\", address = \"127.0.0.1:1\" }}\n"
    ))
    .expect("station")
}

#[test]
fn the_default_is_what_an_empty_plan_file_means() {
    let parsed = TestPlan::from_toml("[serials]\n1 = \"A\"").expect("plan");
    let mut default = TestPlan::default();
    default.serials.insert("1".into(), "A".into());
    assert_eq!(parsed, default);
}

#[test]
fn prefixes_fix_mountings_and_passes_follow() {
    let st = station(2);
    let plan =
        TestPlan::from_toml("[serials]\n1 = \"P:A\"\n2 = \"N:B\"\n7 = \"P:C\"").expect("plan");
    let c = plan.compile(&st).expect("compile");
    // Every serial has a prefix: one mixed pass.
    assert_eq!(c.passes.len(), 1);
    assert_eq!(c.passes[0][0], Some(Mount::P));
    assert_eq!(c.passes[0][1], Some(Mount::N));
    assert_eq!(c.passes[0][2], None);
    assert_eq!(c.serials[1].as_deref(), Some("B"));
    // The published table up and down: 16 levels → 31 level steps.
    let levels = c
        .steps
        .iter()
        .filter(|s| matches!(s, Step::Level { .. }))
        .count();
    assert_eq!(levels, 31);
    let both = TestPlan::from_toml("passes = [\"P\", \"N\"]\n[serials]\n1 = \"A\"\n2 = \"N:B\"")
        .expect("plan");
    let c = both.compile(&st).expect("compile");
    assert_eq!(c.passes.len(), 2);
    assert_eq!(c.passes[0][1], None, "an N-only serial sits out the P pass");
    assert_eq!(c.passes[1][1], Some(Mount::N));
    // With only N-fixed instruments the P pass is not spun at all.
    let n_only = TestPlan::from_toml("passes = [\"P\", \"N\"]\n[serials]\n2 = \"N:B\"")
        .expect("plan")
        .compile(&st)
        .expect("compile");
    assert_eq!(n_only.passes.len(), 1);
    assert_eq!(n_only.passes[0][1], Some(Mount::N));
}

#[test]
fn bad_plans_name_the_key() {
    let st = station(1);
    let cases = [
        (
            "[serials]\n9 = \"A\"",
            "serials.9: slots are numbered 1 to 6",
        ),
        (
            "[serials]\n1 = \"X:A\"",
            "serials.1: 'X:' is not a mounting prefix",
        ),
        (
            "[serials]\n1 = \"A\"\n2 = \"N:A\"",
            "serials.2: 'A' is already in slot 1",
        ),
        (
            "[serials]\n1 = \"P:\"",
            "serials.1: the serial number is empty",
        ),
        (
            "levels = [0, 1, 2]\n[serials]\n1 = \"A\"",
            "levels: 3 levels",
        ),
        (
            "levels = [0, 2, 1, 3, 4, 5]\n[serials]\n1 = \"A\"",
            "strictly ascending",
        ),
        (
            "order = 4\n[serials]\n1 = \"A\"",
            "order: 4 is not 1, 2 or 3",
        ),
        ("[serials]", "serials: no instrument"),
    ];
    for (text, want) in cases {
        let e = TestPlan::from_toml(text)
            .expect("parses")
            .compile(&st)
            .expect_err(text)
            .to_string();
        assert!(e.contains(want), "{text}: {e}");
    }
    let e = TestPlan::from_toml("rnage_g = 5")
        .expect_err("unknown key")
        .to_string();
    assert!(e.contains("rnage_g"), "{e}");
}

#[test]
fn a_slot_written_two_ways_is_refused_not_dropped() {
    // "01" beside "1" named slot 1 twice; one
    // instrument was silently dropped.
    let station = station(1);
    for key in ["01", "+1", " 1"] {
        let text = format!("[serials]\n1 = \"A\"\n\"{key}\" = \"B\"\n");
        let plan = TestPlan::from_toml(&text).expect("plan");
        let e = plan.compile(&station).expect_err(key);
        assert_eq!(e.key, format!("serials.{key}"), "{e}");
    }
    let plan = TestPlan::from_toml("[serials]\n1 = \"A\"\n2 = \"B\"\n").expect("plan");
    assert!(plan.compile(&station).is_ok());
}

#[test]
fn two_counter_modules_of_one_name_are_refused() {
    //
    let fmu = "[[fmu]]\nname = \"f\"\ntransport = { kind = \"tcp\", address = \"127.0.0.1:1\" }\n";
    let text = format!(
        "[arm]\nradius_m = 0.8\nmax_g = 100\n[power]\ninstrument_supply = \"rails\"\n\
         [centrifuge]\nname = \"t\"\nmax_rate_deg_s = 2400\ntransport = {{ kind = \"tcp\", address = \"127.0.0.1:1\" }}\n\
         dialect = {{ kind = \"acutrol\" }}\n{fmu}{fmu}\
         [[power_supply]]\nname = \"rails\"\nchannels = 2\ntransport = {{ kind = \"tcp\", address = \"127.0.0.1:1\" }}\n"
    );
    let e = StationConfig::from_toml(&text).expect_err("two modules named f");
    assert!(e.to_string().contains("fmu[1].name"), "{e}");
}

#[test]
fn a_temperature_the_station_would_stop_at_is_refused_before_anything_moves() {
    // 70 °C on a station with instrument_max_c = 40.
    let fmu = "[[fmu]]\nname = \"f\"\ntransport = { kind = \"tcp\", address = \"127.0.0.1:1\" }\n";
    let text = format!(
        "[arm]\nradius_m = 0.8\nmax_g = 100\n[power]\ninstrument_supply = \"rails\"\n\
         [temperature]\ninstrument_max_c = 40\n\
         [chamber]\nname = \"c\"\ntransport = {{ kind = \"tcp\", address = \"127.0.0.1:1\" }}\n\
         protocol = {{ kind = \"modbus-rtu\", unit_id = 1, setpoint = 100, process_value = 101, run = 102, alarms = 103, counts_per_c = 10 }}\n\
         [centrifuge]\nname = \"t\"\nmax_rate_deg_s = 2400\ntransport = {{ kind = \"tcp\", address = \"127.0.0.1:1\" }}\n\
         dialect = {{ kind = \"acutrol\" }}\n{fmu}\
         [[power_supply]]\nname = \"rails\"\nchannels = 2\ntransport = {{ kind = \"tcp\", address = \"127.0.0.1:1\" }}\n"
    );
    let station = StationConfig::from_toml(&text).expect("station");
    let hot =
        TestPlan::from_toml("temperatures_c = [25, 70]\n[serials]\n1 = \"A\"\n").expect("plan");
    let e = hot.compile(&station).expect_err("70 °C over a 40 °C limit");
    assert_eq!(e.key, "temperatures_c", "{e}");
    assert!(e.to_string().contains("instrument_max_c"), "{e}");
    let mild =
        TestPlan::from_toml("temperatures_c = [25, 35]\n[serials]\n1 = \"A\"\n").expect("plan");
    assert!(mild.compile(&station).is_ok());
}

#[test]
fn look_alike_serials_are_one_serial_and_invisible_characters_are_refused() {
    // A fullwidth Ａ is A (so the second is refused
    // as the same instrument); a zero-width space or a right-to-left
    // override is refused, naming the character.
    let station = station(1);
    let plan = TestPlan::from_toml("[serials]\n1 = \"A1\"\n2 = \"\u{FF21}1\"\n").expect("plan");
    let e = plan.compile(&station).expect_err("A1 twice");
    assert!(e.to_string().contains("already in slot 1"), "{e}");
    for odd in ["A\u{200B}1", "\u{202E}A1"] {
        let text = format!("[serials]\n1 = \"{odd}\"\n");
        let plan = TestPlan::from_toml(&text).expect("plan");
        let e = plan.compile(&station).expect_err(odd);
        assert!(e.to_string().contains("invisible character"), "{e}");
    }
    // A Cyrillic А in a serial is refused, naming it.
    let plan =
        TestPlan::from_toml("[serials]\n1 = \"SN-A1\"\n2 = \"SN-\u{0410}1\"\n").expect("plan");
    let e = plan.compile(&station).expect_err("a look-alike");
    assert!(e.to_string().contains("U+0410"), "{e}");
    let plan = TestPlan::from_toml("[serials]\n1 = \"\u{FF21}7\"\n").expect("plan");
    assert_eq!(
        plan.compile(&station).expect("plan").serials[0].as_deref(),
        Some("A7")
    );
}

#[test]
fn levels_auto_are_designed_for_the_target_before_the_plan_compiles() {
    use spinbench_analysis::design::StationModel;
    let st = station(1);
    let text = "levels = \"auto\"\ntarget_k2_u95_ug_per_g2 = 5\npasses = [\"P\", \"N\"]\n[serials]\n1 = \"A\"";
    let plan = TestPlan::from_toml(text).expect("plan");
    assert!(plan.is_auto());
    // Not designed yet: refused, saying where it is designed.
    let e = plan.compile(&st).expect_err("auto");
    assert_eq!(e.key, "levels");
    assert!(e.problem.contains("designed when a run starts"), "{e}");
    let designed = plan.designed(&StationModel::default()).expect("designed");
    assert!(!designed.is_auto());
    let p = designed.prediction.clone().expect("prediction");
    assert!(p.k2_u95_ug_per_g2 <= 5.0, "{p:?}");
    assert!(
        p.centrifuge_time_s < p.published_centrifuge_time_s.expect("published"),
        "{p:?}"
    );
    assert_eq!(p.target_k2_u95_ug_per_g2, Some(5.0));
    let down = designed.down_levels.clone().expect("down levels");
    let c = designed.compile(&st).expect("compiles as designed");
    let steps = c
        .steps
        .iter()
        .filter(|s| matches!(s, Step::Level { .. }))
        .count();
    assert_eq!(steps, 2 * (designed.level_table().len() + down.len()));
    // The designed plan reads back as itself (plan.toml of the run).
    let again = TestPlan::from_toml(&toml::to_string(&designed).expect("toml")).expect("reads");
    assert_eq!(again, designed);
    // No target: refused, naming the key.
    let e = TestPlan::from_toml("levels = \"auto\"\n[serials]\n1 = \"A\"")
        .expect("plan")
        .designed(&StationModel::default())
        .expect_err("no target");
    assert!(e.problem.contains("target_k2_u95_ug_per_g2"), "{e}");
    // A target no plan reaches: refused before anything moves, with the smallest reachable.
    let e = TestPlan::from_toml(
        "levels = \"auto\"\ntarget_k2_u95_ug_per_g2 = 0.001\n[serials]\n1 = \"A\"",
    )
    .expect("plan")
    .designed(&StationModel::default())
    .expect_err("unreachable");
    assert_eq!(e.key, "target_k2_u95_ug_per_g2");
    assert!(e.problem.contains("the smallest predicted is"), "{e}");
    // A target is for auto levels only; a hostile one is refused by the bounds.
    let e = TestPlan::from_toml("target_k2_u95_ug_per_g2 = 3\n[serials]\n1 = \"A\"")
        .expect("plan")
        .compile(&st)
        .expect_err("target without auto");
    assert_eq!(e.key, "target_k2_u95_ug_per_g2");
    for bad in ["-1", "0", "nan", "inf", "1e300"] {
        let e = TestPlan::from_toml(&format!(
            "levels = \"auto\"\ntarget_k2_u95_ug_per_g2 = {bad}\n[serials]\n1 = \"A\""
        ))
        .expect_err(bad);
        assert_eq!(e.key, "target_k2_u95_ug_per_g2", "{bad}");
    }
    assert!(TestPlan::from_toml("levels = \"manual\"\n[serials]\n1 = \"A\"").is_err());
}

#[test]
fn down_levels_choose_the_readings_on_the_way_down() {
    let st = station(1);
    let compile = |extra: &str| {
        TestPlan::from_toml(&format!(
            "levels = [0, 10, 20, 30, 40, 50]\n{extra}\n[serials]\n1 = \"A\""
        ))
        .expect("plan")
        .compile(&st)
    };
    let c = compile("down_levels = [0, 30]").expect("compile");
    let visits: Vec<(f64, Direction)> = c
        .steps
        .iter()
        .filter_map(|s| match s {
            Step::Level {
                g_nominal,
                direction,
                ..
            } => Some((*g_nominal, *direction)),
            _ => None,
        })
        .collect();
    assert_eq!(
        visits,
        vec![
            (0.0, Direction::Up),
            (10.0, Direction::Up),
            (20.0, Direction::Up),
            (30.0, Direction::Up),
            (40.0, Direction::Up),
            (50.0, Direction::Up),
            (30.0, Direction::Down),
            (0.0, Direction::Down),
        ]
    );
    for (bad, why) in [
        ("down_levels = [25]", "not one of the plan's levels"),
        ("down_levels = [50]", "below the top"),
        ("down_levels = [10, 10]", "listed twice"),
        ("down_levels = [10]\nup_down = false", "needs up_down"),
    ] {
        let e = compile(bad).expect_err(bad);
        assert_eq!(e.key, "down_levels", "{bad}");
        assert!(e.problem.contains(why), "{bad}: {e}");
    }
}

#[test]
fn a_prediction_gives_the_range_of_a_runs_median_for_its_number_of_instruments() {
    use spinbench_analysis::design::StationModel;
    // A station that learned from 10 runs of 12 instruments, their τ spread
    // from 0 to 2,000 µg.
    let model = StationModel {
        between_level_deciles_ug: Some(std::array::from_fn(|i| 200.0 * i as f64)),
        between_level_ug: 1_000.0,
        runs: 10,
        instruments: 120,
        ..StationModel::default()
    };
    let range_of = |serials: usize| {
        let mut text = String::from("passes = [\"P\", \"N\"]\n[serials]\n");
        for s in 1..=serials {
            text.push_str(&format!("{s} = \"S{s}\"\n"));
        }
        let p = TestPlan::from_toml(&text)
            .expect("plan")
            .designed(&model)
            .expect("predicted")
            .prediction
            .expect("prediction");
        let [low, high] = p
            .k2_u95_run_range_ug_per_g2
            .expect("a learned spread gives a range");
        assert!(
            low < p.k2_u95_ug_per_g2 && p.k2_u95_ug_per_g2 < high,
            "{p:?}"
        );
        high - low
    };
    let (one, twelve, unnamed) = (range_of(1), range_of(12), range_of(0));
    assert!(
        twelve < one,
        "12 instruments' median scatters less than one: {twelve} vs {one}"
    );
    // No serials: a run the size of the station's past runs (12).
    assert!((unnamed - twelve).abs() < 1e-9, "{unnamed} vs {twelve}");
    // The defaults (no history) give no range.
    let p = TestPlan::from_toml("[serials]\n1 = \"A\"")
        .expect("plan")
        .designed(&StationModel::default())
        .expect("predicted")
        .prediction
        .expect("prediction");
    assert_eq!(p.k2_u95_run_range_ug_per_g2, None);
}

#[test]
fn a_plan_names_what_its_k2_limit_judges_and_says_beforehand_when_it_cannot_decide() {
    use crate::plan::{Measurand, PlanPrediction};
    // The default is the instrument's own K2; the published convention by name.
    let both = "passes = [\"P\", \"N\"]\n[serials]\n1 = \"A\"\n";
    let plan = TestPlan::from_toml(both).expect("plan");
    assert_eq!(plan.limits.decide_on, Measurand::K2);
    let max =
        TestPlan::from_toml(&format!("{both}[limits]\ndecide_on = \"k2_max\"\n")).expect("plan");
    assert_eq!(max.limits.decide_on, Measurand::K2Max);
    let bad = TestPlan::from_toml(&format!("{both}[limits]\ndecide_on = \"k2\"\n"))
        .expect_err("an unknown measurand");
    assert!(bad.to_string().contains("decide_on"), "{bad}");
    // One mounting has no K2: said before anything moves.
    let one = TestPlan::from_toml("passes = [\"P\"]\n[serials]\n1 = \"A\"\n").expect("plan");
    let w = one.decision_warning().expect("a warning");
    assert!(w.contains("both mountings"), "{w}");
    // A prediction against the limit: none when it leaves room, a warning
    // naming both when it does not.
    let predicted = |u: f64| {
        let mut p = plan.clone();
        p.prediction = Some(PlanPrediction {
            k2_u95_ug_per_g2: u,
            centrifuge_time_s: 1000.0,
            published_k2_u95_ug_per_g2: None,
            published_centrifuge_time_s: None,
            target_k2_u95_ug_per_g2: None,
            k2_u95_run_range_ug_per_g2: None,
            model_runs: 0,
            sequential_centrifuge_time_max_s: None,
        });
        p
    };
    assert_eq!(predicted(4.0).decision_warning(), None);
    let wide = predicted(25.0).decision_warning().expect("a warning");
    assert!(wide.contains("25.000") && wide.contains("20"), "{wide}");
    assert!(predicted(12.0).decision_warning().is_some());
    // Judging k2_max: the prediction (of K2) is not its U95, and it says so.
    let mut on_max = predicted(4.0);
    on_max.limits.decide_on = Measurand::K2Max;
    assert!(
        on_max
            .decision_warning()
            .is_some_and(|w| w.contains("k2_max"))
    );
}
