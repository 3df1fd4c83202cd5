//! A SCPI programmable supply: channels with voltage, current limit and
//! output state, an error queue, and an over-current trip.

use spinbench_wire::scpi::{HeaderSpec, parse_line};
use std::collections::VecDeque;

/// One output.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Output {
    /// Set voltage [V].
    pub volts: f64,
    /// Current limit [A].
    pub current_limit_a: f64,
    /// Output on.
    pub on: bool,
    /// Tripped by over-current (output forced off until switched on again).
    pub tripped: bool,
}

/// A supply.
#[derive(Debug, Clone, PartialEq)]
pub struct Supply {
    /// Identity string.
    pub identity: String,
    /// Outputs, channel 1 first.
    pub outputs: Vec<Output>,
    selected: usize,
    errors: VecDeque<(i32, String)>,
}

impl Supply {
    /// A supply with `channels` outputs, all off.
    pub fn new(identity: &str, channels: usize) -> Supply {
        Supply {
            identity: identity.into(),
            outputs: vec![
                Output {
                    volts: 0.0,
                    current_limit_a: 1.0,
                    on: false,
                    tripped: false
                };
                channels
            ],
            selected: 0,
            errors: VecDeque::new(),
        }
    }

    /// Trip every output on over-current.
    pub fn trip(&mut self) {
        for o in &mut self.outputs {
            if o.on {
                o.on = false;
                o.tripped = true;
            }
        }
        self.errors
            .push_back((-300, "Over-current protection tripped".into()));
    }

    /// Answer one command line; `currents` gives each output's load current
    /// if it were on [A]. Returns the reply line, if the command has one.
    pub fn handle(&mut self, line: &str, currents: &[f64]) -> Option<String> {
        let Ok(cmd) = parse_line(line) else {
            self.errors.push_back((-102, "Syntax error".into()));
            return None;
        };
        let is = |spec: &str| HeaderSpec::new(spec).matches(&cmd);
        let number = |errors: &mut VecDeque<(i32, String)>| -> Option<f64> {
            match cmd.args.first().map(|a| a.parse::<f64>()) {
                Some(Ok(v)) if v.is_finite() && v >= 0.0 => Some(v),
                _ => {
                    errors.push_back((-224, "Illegal parameter value".into()));
                    None
                }
            }
        };
        let ch = self.selected;
        if is("*IDN?") {
            return Some(self.identity.clone());
        } else if is("*CLS") {
            self.errors.clear();
        } else if is("*RST") {
            for o in &mut self.outputs {
                *o = Output {
                    current_limit_a: 1.0,
                    ..Output::default()
                };
            }
        } else if is("INSTrument:NSELect") {
            match cmd.args.first().and_then(|a| a.parse::<usize>().ok()) {
                Some(n) if (1..=self.outputs.len()).contains(&n) => self.selected = n - 1,
                _ => self.errors.push_back((-222, "Data out of range".into())),
            }
        } else if is("VOLTage") {
            if let Some(v) = number(&mut self.errors) {
                if v > 30.0 {
                    self.errors.push_back((-222, "Data out of range".into()));
                } else {
                    self.outputs[ch].volts = v;
                }
            }
        } else if is("CURRent") {
            if let Some(v) = number(&mut self.errors) {
                self.outputs[ch].current_limit_a = v;
            }
        } else if is("OUTPut") {
            match cmd.args.first().map(|a| a.to_ascii_uppercase()) {
                Some(a) if a == "ON" || a == "1" => {
                    self.outputs[ch].on = true;
                    self.outputs[ch].tripped = false;
                }
                Some(a) if a == "OFF" || a == "0" => self.outputs[ch].on = false,
                _ => self
                    .errors
                    .push_back((-224, "Illegal parameter value".into())),
            }
        } else if is("OUTPut?") {
            return Some(if self.outputs[ch].on { "1" } else { "0" }.into());
        } else if is("MEASure:VOLTage?") {
            let o = self.outputs[ch];
            return Some(format!("{:.4}", if o.on { o.volts } else { 0.0 }));
        } else if is("MEASure:CURRent?") {
            let o = self.outputs[ch];
            return Some(format!(
                "{:.5}",
                if o.on {
                    currents.get(ch).copied().unwrap_or(0.0)
                } else {
                    0.0
                }
            ));
        } else if is("SYSTem:ERRor?") {
            let (code, msg) = self.errors.pop_front().unwrap_or((0, "No error".into()));
            return Some(format!("{code},\"{msg}\""));
        } else {
            self.errors.push_back((-113, "Undefined header".into()));
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scpi_settings_measurements_and_errors() {
        let mut s = Supply::new("SIM,PSU", 2);
        assert_eq!(s.handle("*IDN?", &[]), Some("SIM,PSU".into()));
        s.handle("INST:NSEL 2", &[]);
        s.handle("VOLTage 15", &[]);
        s.handle("OUTP ON", &[]);
        assert_eq!(s.handle("MEAS:VOLT?", &[0.0, 0.2]), Some("15.0000".into()));
        assert_eq!(s.handle("MEAS:CURR?", &[0.0, 0.2]), Some("0.20000".into()));
        assert_eq!(s.handle("SYST:ERR?", &[]), Some("0,\"No error\"".into()));
        s.handle("VOLT 99", &[]);
        assert_eq!(
            s.handle("SYST:ERR?", &[]),
            Some("-222,\"Data out of range\"".into())
        );
        s.handle("FOO", &[]);
        assert_eq!(
            s.handle("SYST:ERR?", &[]),
            Some("-113,\"Undefined header\"".into())
        );
        s.trip();
        assert!(s.outputs[1].tripped && !s.outputs[1].on);
    }
}
