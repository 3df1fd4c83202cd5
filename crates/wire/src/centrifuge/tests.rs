//! The dialects against the lines a controller expects and the replies it gives.

use super::*;

fn lines(d: &dyn CentrifugeDialect, r: CentrifugeRequest) -> Vec<String> {
    d.exchanges(&r).into_iter().map(|e| e.line).collect()
}

#[test]
fn acutrol_sends_long_or_short_forms() {
    let long = AcutrolDialect::default();
    assert_eq!(
        lines(&long, CentrifugeRequest::SetRate { rate_deg_s: 360.5 }),
        vec![":DEMAND:RATE 1,360.5", ":MODE:RATE 1"]
    );
    assert_eq!(
        lines(&long, CentrifugeRequest::ReadRate),
        vec![":READ:RATE? 1"]
    );
    assert_eq!(lines(&long, CentrifugeRequest::Stop), vec![":MODE:OFF 1"]);
    assert_eq!(
        lines(&long, CentrifugeRequest::Arm),
        vec![":INTERLOCK:CLOSE 1"]
    );
    let short = AcutrolDialect {
        axis: 2,
        short_form: true,
    };
    assert_eq!(
        lines(&short, CentrifugeRequest::SetRate { rate_deg_s: 90.0 }),
        vec![":DEM:RAT 2,90", ":MOD:RAT 2"]
    );
    assert_eq!(
        lines(&short, CentrifugeRequest::ReadInterlocks),
        vec![":INT?"]
    );
    assert_eq!(lines(&short, CentrifugeRequest::Identify), vec!["*IDN?"]);
}

#[test]
fn acutrol_replies_parse() {
    let d = AcutrolDialect::default();
    assert_eq!(
        d.parse_reply(&CentrifugeRequest::ReadRate, "+3.6000E+02\r"),
        Ok(CentrifugeReply::RateDegS(360.0))
    );
    assert_eq!(
        d.parse_reply(&CentrifugeRequest::ReadInterlocks, "CLOSED"),
        Ok(CentrifugeReply::Interlocks(true))
    );
    assert_eq!(
        d.parse_reply(&CentrifugeRequest::ReadInterlocks, "0"),
        Ok(CentrifugeReply::Interlocks(false))
    );
    assert!(matches!(
        d.parse_reply(&CentrifugeRequest::ReadRate, "#!"),
        Err(DialectReplyError::Garbled(_))
    ));
}

const MNEMONIC_TOML: &str = r#"
    name = "TurnMaster 3000"
    line_ending = "\r"
    rate_unit = "rpm"
    rate_decimals = 2
    [commands]
    identify = "ID?"
    arm = "ENA"
    disarm = "DIS"
    set_rate = "JOG {rate}"
    read_rate = "RATE?"
    read_interlocks = "ILK?"
    stop = "STO"
    [replies]
    read_rate = '^RATE\s+(?P<rate>[-+0-9.eE]+)$'
    read_interlocks = '^ILK (?P<closed>[01])$'
    ack = '^OK$'
    error = '^ERR (?P<message>.*)$'
"#;

#[test]
fn a_configured_dialect_needs_no_code() {
    let config: LineDialectConfig = toml::from_str(MNEMONIC_TOML).expect("toml");
    let d = LineDialect::new(config).expect("valid");
    assert_eq!(d.line_ending(), "\r");
    // 360 deg/s is 60 rpm.
    let ex = d.exchanges(&CentrifugeRequest::SetRate { rate_deg_s: 360.0 });
    assert_eq!(
        ex,
        vec![Exchange {
            line: "JOG 60.00".into(),
            expect: Expect::Ack
        }]
    );
    assert_eq!(
        d.parse_reply(&CentrifugeRequest::ReadRate, "RATE 30.5"),
        Ok(CentrifugeReply::RateDegS(183.0))
    );
    assert_eq!(
        d.parse_reply(&CentrifugeRequest::ReadInterlocks, "ILK 1"),
        Ok(CentrifugeReply::Interlocks(true))
    );
    assert_eq!(d.check_ack("OK"), Ok(()));
    assert_eq!(
        d.check_ack("ERR overspeed"),
        Err(DialectReplyError::Refused("overspeed".into()))
    );
    assert!(matches!(
        d.check_ack("what?"),
        Err(DialectReplyError::Garbled(_))
    ));
    assert!(d.exchanges(&CentrifugeRequest::ResetInterlocks).is_empty());
}

#[test]
fn bad_dialect_configs_name_the_key() {
    let base: LineDialectConfig = toml::from_str(MNEMONIC_TOML).expect("toml");
    let mut c = base.clone();
    c.commands.set_rate = "JOG".into();
    assert!(
        LineDialect::new(c)
            .expect_err("no {rate}")
            .to_string()
            .contains("commands.set_rate")
    );
    let mut c = base.clone();
    c.replies.read_rate = "^RATE (.*)$".into();
    let e = LineDialect::new(c).expect_err("no group").to_string();
    assert!(
        e.contains("replies.read_rate: the pattern needs a named group (?P<rate>"),
        "{e}"
    );
    let mut c = base;
    c.replies.ack = Some("(".into());
    assert!(
        LineDialect::new(c)
            .expect_err("bad regex")
            .to_string()
            .contains("replies.ack: not a valid regular expression")
    );
    let unknown = MNEMONIC_TOML.replace("stop = \"STO\"", "stop = \"STO\"\nhalt = \"H\"");
    let e = toml::from_str::<LineDialectConfig>(&unknown)
        .expect_err("unknown key")
        .to_string();
    assert!(e.contains("halt"), "{e}");
}
