//! SCPI-style command lines (IEEE 488.2): parsing with abbreviations (the
//! instrument side, used by the simulator), and reply parsing (the driver side).
//!
//! A header is a path of mnemonics (`:MODe:RATe`), optionally a query
//! (`?`), then comma-separated arguments. A mnemonic may be sent in its long
//! form or its short form, the upper-case letters of its specification
//! (`MODe` accepts `MODE` and `MOD`), in any case. Common commands start with
//! `*` (`*IDN?`).

use std::fmt;

/// A parsed command line.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CommandLine {
    /// Mnemonics of the header, upper-cased, without colons (`["MODE", "RATE"]`,
    /// or `["*IDN"]`).
    pub header: Vec<String>,
    /// True if the header ended in `?`.
    pub query: bool,
    /// Arguments, trimmed.
    pub args: Vec<String>,
}

/// A line that is not a command.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{problem} in command line '{line}'")]
pub struct ParseError {
    /// The line, as received.
    pub line: String,
    /// What is wrong.
    pub problem: &'static str,
}

/// Parse one command line (without its terminator).
pub fn parse_line(line: &str) -> Result<CommandLine, ParseError> {
    let err = |problem| ParseError {
        line: line.to_string(),
        problem,
    };
    let trimmed = line.trim();
    if trimmed.is_empty() {
        return Err(err("empty header"));
    }
    let (head, rest) = match trimmed.find(char::is_whitespace) {
        Some(i) => (&trimmed[..i], trimmed[i..].trim()),
        None => (trimmed, ""),
    };
    let (head, query) = match head.strip_suffix('?') {
        Some(h) => (h, true),
        None => (head, false),
    };
    let header: Vec<String> = if let Some(common) = head.strip_prefix('*') {
        if common.is_empty() || !common.chars().all(|c| c.is_ascii_alphabetic()) {
            return Err(err("bad common command"));
        }
        vec![format!("*{}", common.to_ascii_uppercase())]
    } else {
        let path = head.strip_prefix(':').unwrap_or(head);
        let parts: Vec<&str> = path.split(':').collect();
        if parts
            .iter()
            .any(|p| p.is_empty() || !p.chars().all(|c| c.is_ascii_alphanumeric() || c == '_'))
        {
            return Err(err("bad header"));
        }
        parts.iter().map(|p| p.to_ascii_uppercase()).collect()
    };
    let args = if rest.is_empty() {
        Vec::new()
    } else {
        rest.split(',').map(|a| a.trim().to_string()).collect()
    };
    if args.iter().any(String::is_empty) {
        return Err(err("empty argument"));
    }
    Ok(CommandLine {
        header,
        query,
        args,
    })
}

/// A header specification such as `:MODe:RATe` or `*IDN`, in SCPI's
/// mixed-case notation (upper-case letters are the short form).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct HeaderSpec {
    /// Per mnemonic: (long form, short form), both upper case.
    mnemonics: Vec<(String, String)>,
    query: bool,
}

impl HeaderSpec {
    /// A spec from SCPI notation; a trailing `?` makes it a query.
    pub fn new(spec: &str) -> HeaderSpec {
        let (spec, query) = match spec.strip_suffix('?') {
            Some(s) => (s, true),
            None => (spec, false),
        };
        let path = spec.strip_prefix(':').unwrap_or(spec);
        let mnemonics = path
            .split(':')
            .map(|m| {
                let short: String = m
                    .chars()
                    .filter(|c| c.is_ascii_uppercase() || *c == '*' || c.is_ascii_digit())
                    .collect();
                (m.to_ascii_uppercase(), short)
            })
            .collect();
        HeaderSpec { mnemonics, query }
    }

    /// Does `command` address this header (long or short form of every mnemonic)?
    pub fn matches(&self, command: &CommandLine) -> bool {
        command.query == self.query
            && command.header.len() == self.mnemonics.len()
            && command
                .header
                .iter()
                .zip(&self.mnemonics)
                .all(|(got, (long, short))| got == long || got == short)
    }

    /// The header in long or short form, e.g. `:MODE:RATE` or `:MOD:RAT`.
    pub fn render(&self, short: bool) -> String {
        let mut out = String::new();
        for (long, short_form) in &self.mnemonics {
            if !long.starts_with('*') {
                out.push(':');
            }
            out.push_str(if short { short_form } else { long });
        }
        if self.query {
            out.push('?');
        }
        out
    }
}

impl fmt::Display for HeaderSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.render(false))
    }
}

/// A reply that does not parse.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("expected {expected}, got '{reply}'")]
pub struct ReplyError {
    /// What was expected.
    pub expected: &'static str,
    /// The reply received.
    pub reply: String,
}

/// A numeric reply (NR1/NR2/NR3; `+`, exponent and surrounding spaces allowed).
pub fn parse_number(reply: &str) -> Result<f64, ReplyError> {
    reply
        .trim()
        .parse::<f64>()
        .ok()
        .filter(|v| v.is_finite())
        .ok_or_else(|| ReplyError {
            expected: "a number",
            reply: reply.to_string(),
        })
}

/// A boolean reply: `1`/`0` or `ON`/`OFF`.
pub fn parse_bool(reply: &str) -> Result<bool, ReplyError> {
    match reply.trim().to_ascii_uppercase().as_str() {
        "1" | "ON" => Ok(true),
        "0" | "OFF" => Ok(false),
        _ => Err(ReplyError {
            expected: "1/0 or ON/OFF",
            reply: reply.to_string(),
        }),
    }
}

/// An entry of the IEEE 488.2 error queue: `-113,"Undefined header"`; code 0 is "no error".
pub fn parse_error_entry(reply: &str) -> Result<(i32, String), ReplyError> {
    let bad = || ReplyError {
        expected: "an error-queue entry like 0,\"No error\"",
        reply: reply.to_string(),
    };
    let (code, message) = reply.trim().split_once(',').ok_or_else(bad)?;
    let code = code.trim().parse::<i32>().map_err(|_| bad())?;
    let message = message.trim().trim_matches('"').to_string();
    Ok((code, message))
}

/// Format a number for a command argument: plain decimal, enough digits
/// for 1e-9 relative resolution, no exponent.
pub fn format_number(value: f64) -> String {
    let text = format!("{value:.9}");
    let text = text.trim_end_matches('0');
    text.strip_suffix('.').unwrap_or(text).to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn abbreviations_match_in_any_case() {
        let spec = HeaderSpec::new(":MODe:RATe");
        for line in [":MODE:RATE 1", "MOD:RAT 1", ":mod:rate 1", ":Mode:Rat 1"] {
            let cmd = parse_line(line).expect("parses");
            assert!(spec.matches(&cmd), "{line}");
            assert_eq!(cmd.args, vec!["1"]);
        }
        for line in [":MO:RATE 1", ":MODES:RATE 1", ":MODE:RATE? 1"] {
            let cmd = parse_line(line).expect("parses");
            assert!(!spec.matches(&cmd), "{line}");
        }
        assert_eq!(spec.render(false), ":MODE:RATE");
        assert_eq!(spec.render(true), ":MOD:RAT");
        let idn = HeaderSpec::new("*IDN?");
        assert!(idn.matches(&parse_line("*idn?").expect("parses")));
        assert_eq!(idn.render(true), "*IDN?");
    }

    #[test]
    fn arguments_and_queries() {
        let cmd = parse_line("  :DEMand:RATe 1, 360.5 ").expect("parses");
        assert_eq!(cmd.header, vec!["DEMAND", "RATE"]);
        assert!(!cmd.query);
        assert_eq!(cmd.args, vec!["1", "360.5"]);
        let q = parse_line(":READ:RATE? 1").expect("parses");
        assert!(q.query);
        for bad in ["", "::MODE", ":MODE:RATE 1,,2", "*", ":MO$DE"] {
            assert!(parse_line(bad).is_err(), "{bad:?}");
        }
    }

    #[test]
    fn replies_parse_or_say_what_was_expected() {
        assert_eq!(parse_number(" +3.6E+2\r"), Ok(360.0));
        assert!(parse_number("NaN").is_err());
        assert_eq!(parse_bool("ON"), Ok(true));
        assert_eq!(
            parse_error_entry("-113,\"Undefined header\""),
            Ok((-113, "Undefined header".into()))
        );
        assert_eq!(
            parse_error_entry("0,\"No error\""),
            Ok((0, "No error".into()))
        );
        let e = parse_number("garbage").expect_err("not a number");
        assert_eq!(e.to_string(), "expected a number, got 'garbage'");
    }

    #[test]
    fn numbers_format_without_exponent() {
        assert_eq!(format_number(360.0), "360");
        assert_eq!(format_number(1234.5678), "1234.5678");
        assert_eq!(format_number(-0.25), "-0.25");
        assert_eq!(format_number(1e-7), "0.0000001");
    }
}
