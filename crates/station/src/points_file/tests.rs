use super::*;

fn parse(text: &str) -> Result<PointsFile, PointsFileError> {
    parse_csv(Path::new("t.csv"), text.as_bytes())
}

#[test]
fn column_letters_match_spreadsheets() {
    assert_eq!(column_letters(0), "A");
    assert_eq!(column_letters(25), "Z");
    assert_eq!(column_letters(26), "AA");
    assert_eq!(column_letters(701), "ZZ");
    assert_eq!(column_letters(702), "AAA");
}

#[test]
fn reads_columns_in_any_order_with_bom_and_comments() {
    let f = parse(
        "\u{feff}Output, MOUNT,unit,g_applied,g_nominal,notes\n# a comment\n35.5,P,SN1,,0,x\n135.6,p,SN1,1.0004,1,\n",
    )
    .expect("parse");
    assert_eq!(f.rows, 2);
    let u = &f.units[0];
    assert_eq!(u.unit, "SN1");
    assert_eq!(u.points[0].g_applied, 0.0);
    assert_eq!(u.points[1].g_applied, 1.0004);
    assert_eq!(u.points[1].output, 135.6);
}

#[test]
fn groups_by_unit_and_run_in_first_appearance_order() {
    let f = parse(
        "unit,mount,g_nominal,g_applied,output,run\nB,P,0,,1,r1\nA,P,0,,1,r1\nB,P,1,,2,r1\nB,P,0,,1,r2\n",
    )
    .expect("parse");
    let keys: Vec<(String, Option<String>, usize)> = f
        .units
        .iter()
        .map(|u| (u.unit.clone(), u.run.clone(), u.points.len()))
        .collect();
    assert_eq!(
        keys,
        vec![
            ("B".into(), Some("r1".into()), 2),
            ("A".into(), Some("r1".into()), 1),
            ("B".into(), Some("r2".into()), 1)
        ]
    );
}

#[test]
fn a_repeated_block_is_refused_and_a_single_repeated_row_is_said() {
    let head = "unit,mount,g_nominal,g_applied,output\n";
    let block = "A,P,0,0,1\nA,P,5,5,501\nA,P,10,10,1001\n";
    let e = parse(&format!("{head}{block}{block}")).expect_err("appended twice");
    let message = e.to_string();
    assert!(
        message.contains(":5") && message.contains("line 2"),
        "{message}"
    );
    assert!(message.contains("appended twice"), "{message}");
    let one = parse(&format!("{head}{block}A,P,5,5,501\n")).expect("a coincident reading");
    assert_eq!(one.rows, 4);
    assert_eq!(one.warnings.len(), 1);
    assert!(
        one.warnings[0].contains("line 5 repeats line 3"),
        "{:?}",
        one.warnings
    );
    // A level visited again with another reading is a new point.
    let ok = parse("unit,mount,g_nominal,g_applied,output\nA,P,0,0,1\nA,P,0,0,1.0001\n")
        .expect("a repeated visit");
    assert_eq!(ok.rows, 2);
}

#[test]
fn errors_name_line_and_column() {
    let head = "unit,mount,g_nominal,g_applied,output\n";
    let cases = [
        ("", "no rows"),
        ("SN1,P,0,,1\n", "expected a header row"),
        (
            "unit,mount,g_nominal,output\nA,P,0,1\n",
            "missing column(s) g_applied",
        ),
        (
            "unit,mount,unit,g_nominal,g_applied,output\n",
            "t.csv:1: column 3 (unit): duplicate header",
        ),
        (
            &format!("{head}A,X,0,,1\n"),
            "t.csv:2: column 2 (mount): expected P",
        ),
        (
            &format!("{head}A,P,zero,,1\n"),
            "t.csv:2: column 3 (g_nominal): expected a number, found 'zero'",
        ),
        (
            &format!("{head}A,P,0,,NaN\n"),
            "t.csv:2: column 5 (output): expected a finite number",
        ),
        (
            &format!("{head}A,P,0,,inf\n"),
            "column 5 (output): expected a finite number",
        ),
        (
            &format!("{head}A,P,0,,\n"),
            "column 5 (output): expected the averaged",
        ),
        (
            &format!("{head},P,0,,1\n"),
            "column 1 (unit): expected a unit serial",
        ),
        (head, "no data rows"),
    ];
    for (text, want) in cases {
        let err = parse(text).expect_err(text).to_string();
        assert!(
            err.contains(want),
            "input {text:?}\n  got: {err}\n want: {want}"
        );
    }
}

#[test]
fn invalid_utf8_is_an_error_not_a_panic() {
    let err = parse_csv(
        Path::new("b.csv"),
        b"unit,mount,g_nominal,g_applied,output\nA\xff,P,0,,1\n",
    )
    .expect_err("bad utf8");
    assert!(err.to_string().contains("b.csv:2: column 1"), "{err}");
}
