//! The devices' command sides: counter-module messages, the centrifuge
//! controller's dialects, the supplies' SCPI lines.

use super::{
    FIRMWARE_ID, HeaderSpec, Message, SimDialect, StatusReply, SupplyId, TICKS_PER_SECOND, World,
    h, parse_line, scpi,
};

impl World {
    /// A frame from the station to module `m`; returns the bytes of the reply.
    pub fn handle_module_message(&mut self, m: usize, message: Result<Message, ()>) -> Vec<u8> {
        if m >= self.modules.len() || !self.module_alive(m) {
            return Vec::new();
        }
        let Ok(message) = message else {
            self.modules[m].rx_crc_errors = self.modules[m].rx_crc_errors.wrapping_add(1);
            return Vec::new();
        };
        self.addressed[m] = true;
        let cmd = message.command() as u8;
        let ack = |result| Message::Ack { cmd, result };
        let module = &mut self.modules[m];
        let reply = match message {
            Message::SetPower { mask } => {
                module.relay_mask = mask & 0x3F;
                ack(0)
            }
            Message::StartStreaming { mode } => {
                let second = u64::from(TICKS_PER_SECOND);
                module.streaming = Some(mode);
                module.stream_from_tick = self.tick.div_ceil(second) * second;
                self.has_streamed = true;
                self.lockstep_start();
                ack(0)
            }
            Message::StopStreaming => {
                module.streaming = None;
                if !self.streaming_any() {
                    self.lockstep_running = false;
                }
                ack(0)
            }
            Message::StatusRequest => Message::Status(StatusReply {
                firmware_id: FIRMWARE_ID,
                relay_mask: module.relay_mask,
                rx_crc_errors: module.rx_crc_errors,
                rx_tail_errors: 0,
                overruns: module.overruns,
            }),
            // A message only a module sends: not a command.
            _ => ack(1),
        };
        let mut out = Vec::new();
        let _ = reply.encode(&mut out);
        out
    }

    /// A line from the station to the centrifuge controller; returns the reply line.
    pub fn handle_centrifuge_line(&mut self, line: &str) -> Option<String> {
        if self.centrifuge_silent {
            return None;
        }
        match self.config.centrifuge.dialect {
            SimDialect::Acutrol => self.acutrol(line),
            SimDialect::Mnemonic => self.mnemonic(line),
        }
    }

    pub(super) fn demand(&mut self, rate_deg_s: f64) -> Result<(), (i32, &'static str)> {
        if !rate_deg_s.is_finite() || rate_deg_s.abs() > self.config.centrifuge.max_rate_deg_s {
            return Err((-222, "Data out of range; rate above the table limit"));
        }
        self.table.demand_rad_s = rate_deg_s.to_radians();
        Ok(())
    }

    pub(super) fn acutrol(&mut self, line: &str) -> Option<String> {
        let Ok(cmd) = parse_line(line) else {
            self.centrifuge_errors
                .push_back((-102, "Syntax error".into()));
            return None;
        };
        let is = |spec: &str| HeaderSpec::new(spec).matches(&cmd);
        let number = |i: usize| cmd.args.get(i).and_then(|a| scpi::parse_number(a).ok());
        if is(h::IDN) {
            return Some("ACUTRONIC,SPINBENCH-SIM,0,1.0".into());
        } else if is(h::STB) {
            let stb = u8::from(self.table.interlocks_closed)
                | (u8::from(self.table.rate_mode) << 1)
                | (u8::from(self.table.interlock_fault) << 2);
            return Some(stb.to_string());
        } else if is(h::READ_RATE) {
            let reply = format!("{:.6}", self.table.reported_rate_rad_s().to_degrees());
            self.lockstep_barrier();
            return Some(reply);
        } else if is(h::INTERLOCK_QUERY) {
            return Some(
                if self.table.interlocks_closed {
                    "1"
                } else {
                    "0"
                }
                .into(),
            );
        } else if is(h::SYSTEM_ERROR) {
            let (code, msg) = self
                .centrifuge_errors
                .pop_front()
                .unwrap_or((0, "No error".into()));
            return Some(format!("{code},\"{msg}\""));
        } else if is(h::DEMAND_RATE) {
            match number(1) {
                Some(r) => {
                    if let Err((code, msg)) = self.demand(r) {
                        self.centrifuge_errors.push_back((code, msg.into()));
                    }
                }
                None => self
                    .centrifuge_errors
                    .push_back((-109, "Missing parameter".into())),
            }
        } else if is(h::MODE_RATE) {
            if self.table.interlocks_closed {
                self.table.rate_mode = true;
            } else {
                self.centrifuge_errors
                    .push_back((-221, "Settings conflict; interlocks open".into()));
            }
        } else if is(h::MODE_OFF) {
            self.table.rate_mode = false;
            self.table.demand_rad_s = 0.0;
        } else if is(h::INTERLOCK_CLOSE) {
            if self.table.interlock_fault {
                self.centrifuge_errors.push_back((
                    -221,
                    "Settings conflict; interlock fault latched, reset first".into(),
                ));
            } else {
                self.table.interlocks_closed = true;
            }
        } else if is(h::INTERLOCK_OPEN) {
            self.table.interlocks_closed = false;
            self.table.rate_mode = false;
        } else if is(h::INTERLOCK_RESET) {
            self.table.interlock_fault = false;
        } else if is(h::LIMIT_RATE) || is(h::LIMIT_ACCELERATION) {
            // Accepted; the simulated table keeps its configured physical limits.
        } else {
            self.centrifuge_errors
                .push_back((-113, "Undefined header".into()));
        }
        None
    }

    pub(super) fn mnemonic(&mut self, line: &str) -> Option<String> {
        let mut words = line.split_whitespace();
        let verb = words.next().unwrap_or("").to_ascii_uppercase();
        let arg = words.next();
        Some(match verb.as_str() {
            "ID?" => "SPINBENCH SIM-TABLE MNEMONIC 1.0".into(),
            "RATE?" => {
                let reply = format!(
                    "RATE {:.4}",
                    spinbench_analysis::centrifuge::rad_s_to_rpm(self.table.reported_rate_rad_s())
                );
                self.lockstep_barrier();
                reply
            }
            "ILK?" => format!("ILK {}", u8::from(self.table.interlocks_closed)),
            "ENA" if self.table.interlock_fault => "ERR interlock fault latched, send RST".into(),
            "ENA" => {
                self.table.interlocks_closed = true;
                self.table.rate_mode = true;
                "OK".into()
            }
            "DIS" => {
                self.table.interlocks_closed = false;
                "OK".into()
            }
            "RST" => {
                self.table.interlock_fault = false;
                "OK".into()
            }
            "STO" => {
                self.table.demand_rad_s = 0.0;
                "OK".into()
            }
            "JOG" => match arg.and_then(|a| a.parse::<f64>().ok()) {
                Some(rpm) => match self.demand(rpm * 6.0) {
                    Ok(()) => "OK".into(),
                    Err(_) => "ERR overspeed".into(),
                },
                None => "ERR missing rate".into(),
            },
            _ => "ERR unknown command".into(),
        })
    }

    /// A line from the station to a supply; returns the reply line.
    pub fn handle_supply_line(&mut self, which: SupplyId, line: &str) -> Option<String> {
        match which {
            SupplyId::Rails => {
                let currents = self.rail_currents();
                self.rails.handle(line, &currents)
            }
            SupplyId::Logic => {
                let currents = self.logic_currents();
                self.logic.handle(line, &currents)
            }
        }
    }
}
