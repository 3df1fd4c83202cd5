use super::*;

#[test]
fn a_dof_that_is_whole_up_to_rounding_gets_its_whole_coverage_factor() {
    let t14 = student_t_975(14).expect("t");
    assert_eq!(coverage_factor_95(Some(13.999_999_999_999_998)), t14);
    assert_eq!(coverage_factor_95(Some(14.0)), t14);
    // Fractional: rounded down, conservative.
    assert_eq!(coverage_factor_95(Some(14.5)), t14);
    assert_eq!(
        coverage_factor_95(Some(13.9)),
        student_t_975(13).expect("t")
    );
    assert_eq!(coverage_factor_95(None), 1.959_964);
    let single = combine(vec![(Source::Repeatability, 1.0, Some(14.0 - 2e-15))]);
    assert_eq!(single.u95, t14);
}
