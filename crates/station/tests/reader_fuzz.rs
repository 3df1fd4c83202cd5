//! Property tests of the points-file reader: arbitrary bytes, and
//! arbitrary cells under a valid header, never panic.

use proptest::prelude::*;
use spinbench_station::points_file::parse_csv;
use std::path::Path;

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..600)) {
        let _ = parse_csv(Path::new("fuzz.csv"), &bytes);
    }

    #[test]
    fn arbitrary_cells_give_rows_or_a_located_error(
        rows in proptest::collection::vec(
            proptest::collection::vec(
                prop_oneof![
                    Just(String::new()),
                    Just("P".to_string()),
                    Just("N".to_string()),
                    "-?[0-9]{1,3}(\\.[0-9]{1,4})?",
                    "[ -~]{0,6}",
                    Just("NaN".to_string()),
                    Just("1e999".to_string()),
                ],
                0..7,
            ),
            0..20,
        )
    ) {
        let mut text = String::from("unit,mount,g_nominal,g_applied,output\n");
        for row in &rows {
            text.push_str(&row.join(","));
            text.push('\n');
        }
        match parse_csv(Path::new("cells.csv"), text.as_bytes()) {
            Ok(file) => {
                let points: usize = file.units.iter().map(|u| u.points.len()).sum();
                prop_assert_eq!(points, file.rows);
                for u in &file.units {
                    for p in &u.points {
                        prop_assert!(p.output.is_finite() && p.g_applied.is_finite());
                    }
                }
            }
            Err(e) => prop_assert!(e.to_string().starts_with("cells.csv"), "{}", e),
        }
    }
}
