use super::ports::take_lines;
use super::*;

#[test]
fn lines_split_on_any_terminator() {
    let mut p = b"*IDN?\r\nRATE?\rILK".to_vec();
    assert_eq!(
        take_lines(&mut p),
        vec!["*IDN?".to_string(), "RATE?".to_string()]
    );
    assert_eq!(p, b"ILK".to_vec());
}

#[test]
fn control_commands() {
    let mut w = World::new(SimConfig::default());
    assert_eq!(
        control_command(&mut w, "MOUNT ALL UP").as_deref(),
        Some("OK")
    );
    assert_eq!(control_command(&mut w, "MOUNT 3 N").as_deref(), Some("OK"));
    assert!(control_command(&mut w, "MOUNT 99 N").is_some_and(|r| r.starts_with("ERR")));
    assert!(control_command(&mut w, "TRUTH?").is_some_and(|r| r.contains("k2_ug_per_g2")));
    assert_eq!(control_command(&mut w, "TIME?").as_deref(), Some("0.0000"));
}
