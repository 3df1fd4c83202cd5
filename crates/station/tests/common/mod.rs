//! Shared by the station's integration tests.

/// A short two-mounting plan for the virtual bench (±10 g, 7 levels, no
/// warm-up, 3-s dwell and hold) with instruments `{prefix}1`, `{prefix}2`
/// (module 1) and `{prefix}7` (module 2).
pub fn short_plan(prefix: &str) -> String {
    format!(
        r#"
range_g = 10
levels = [0, 1, 2, 4, 6, 8, 10]
passes = ["P", "N"]
warmup_s = 0
dwell = {{ seconds = 3 }}
stability = {{ hold_s = 3 }}
[serials]
1 = "{prefix}1"
2 = "{prefix}2"
7 = "{prefix}7"
"#
    )
}
