use super::*;

fn test(serial: &str, k2: f64) -> BatchTest {
    BatchTest {
        run_id: "r".into(),
        started_at: 0,
        serial: serial.into(),
        slot: 0,
        radius_m: BTreeMap::new(),
        outcome: Outcome::Pass,
        k2_max_ug_per_g2: Some(k2.abs()),
        k2_ug_per_g2: Some(k2),
        k1_hz_per_g: Some(100.0),
        sf_nonlinearity_ppm: None,
        asymmetry_ppm: None,
        analysis: None,
        temperature_coefficients: None,
    }
}

#[test]
fn statistics_histogram_and_a_robust_outlier() {
    let mut tests: Vec<BatchTest> = (0..20)
        .map(|i| test(&format!("S{i}"), 10.0 + f64::from(i % 5) * 0.1))
        .collect();
    tests.push(test("WILD", 25.0));
    let d = distribution("k2", "µg/g²", &tests, |t| t.k2_ug_per_g2).expect("d");
    assert_eq!(d.n, 21);
    let mean = (20.0 * 10.2 + 25.0) / 21.0;
    assert!((d.mean - mean).abs() < 1e-12);
    assert_eq!((d.min, d.max), (10.0, 25.0));
    assert_eq!(d.bins.iter().map(|b| b.2).sum::<usize>(), 21);
    assert_eq!(d.bins.len(), 6, "Sturges: ⌈log2 21⌉ + 1");
    assert_eq!(d.outliers.len(), 1);
    assert_eq!(d.outliers[0].serial, "WILD");
    // No figure at all: no distribution.
    assert!(distribution("x", "", &tests, |t| t.asymmetry_ppm).is_none());
}

#[test]
fn temperature_coefficients_get_their_distributions_only_when_measured() {
    let (name, _, value) = FIGURES[5];
    let tests: Vec<BatchTest> = (0..10).map(|i| test(&format!("S{i}"), 10.0)).collect();
    assert!(
        distribution(name, "", &tests, value).is_none(),
        "none measured"
    );
    let with: Vec<BatchTest> = (0..10)
        .map(|i| BatchTest {
            temperature_coefficients: Some(
                spinbench_analysis::temperature::TemperatureCoefficients {
                    k0_ug_per_c: f64::from(i),
                    k0_ug_per_c_u95: 1.0,
                    k1_ppm_per_c: 0.0,
                    k1_ppm_per_c_u95: 1.0,
                    k2_ug_per_g2_per_c: None,
                    k2_ug_per_g2_per_c_u95: None,
                    temperatures: 3,
                    u: Default::default(),
                    chi2: Default::default(),
                    batch: None,
                },
            ),
            ..test(&format!("S{i}"), 10.0)
        })
        .collect();
    let d = distribution(name, "µg/°C", &with, value).expect("k0 coefficients");
    assert_eq!((d.n, d.mean), (10, 4.5));
    let (k2_name, _, k2_value) = FIGURES[7];
    assert!(
        distribution(k2_name, "", &with, k2_value).is_none(),
        "no K2 coefficient"
    );
}
