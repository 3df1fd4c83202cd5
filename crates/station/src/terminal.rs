//! The terminal's side of a run: the operator at the keyboard (prompts on
//! stderr, Enter or `abort` on stdin) and the progress printer.

use spinbench_engine::event::{Event, EventSink};
use spinbench_engine::plan::Fixture;
use spinbench_engine::{Answer, Operator};
use std::io::IsTerminal;
use std::time::{Duration, Instant};

/// The terminal operator: shows the prompt, waits for Enter (or `abort`).
/// Standard input is read on its own thread, so the engine keeps reading
/// the counter modules while the operator works at the centrifuge.
#[derive(Default)]
pub struct TerminalOperator {
    lines: Option<std::sync::mpsc::Receiver<Option<String>>>,
}

impl TerminalOperator {
    fn answer_of(line: Option<String>) -> Answer {
        let proceed = line
            .as_deref()
            .is_some_and(|l| !l.trim().eq_ignore_ascii_case("abort"));
        Answer {
            proceed,
            by: "operator at the terminal".into(),
        }
    }
}

impl Operator for TerminalOperator {
    fn ask(&mut self, text: &str, fixtures: &[Option<Fixture>]) -> Answer {
        if let Some(answer) = self.post(text, fixtures) {
            return answer;
        }
        loop {
            if let Some(answer) = self.poll_answer(Duration::from_millis(500)) {
                return answer;
            }
        }
    }

    fn post(&mut self, text: &str, _fixtures: &[Option<Fixture>]) -> Option<Answer> {
        eprintln!(
            "\n>>> {text}\n    Press Enter when done, or type 'abort' and Enter to stop the run safely."
        );
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let mut line = String::new();
            let read = std::io::stdin().read_line(&mut line);
            // End of input (or an unreadable terminal) is no "done".
            let _ = tx.send(matches!(read, Ok(n) if n > 0).then_some(line));
        });
        self.lines = Some(rx);
        None
    }

    fn poll_answer(&mut self, wait: Duration) -> Option<Answer> {
        let rx = self.lines.as_ref()?;
        match rx.recv_timeout(wait) {
            Ok(line) => {
                self.lines = None;
                Some(Self::answer_of(line))
            }
            Err(std::sync::mpsc::RecvTimeoutError::Timeout) => None,
            Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => {
                self.lines = None;
                Some(Self::answer_of(None))
            }
        }
    }
}

/// Progress on stderr: the step, the phase, the rate.
pub struct ProgressPrinter {
    tty: bool,
    step: String,
    steps: (usize, usize),
    phase: String,
    last: Instant,
    quiet: bool,
    /// The instruments' temperatures, coldest and warmest slot [°C].
    temperatures_c: Option<(f64, f64)>,
    /// Every slot's state, as the web UI's board shows it.
    board: spinbench_engine::board::SlotBoard,
}

/// "9 averaging, 1 failed": how many slots are in each state.
fn phase_counts(board: &spinbench_engine::board::SlotBoard) -> String {
    let mut counts: Vec<(&str, usize)> = Vec::new();
    for s in board.slots() {
        let name = s.phase.as_str();
        match counts.iter_mut().find(|(n, _)| *n == name) {
            Some((_, c)) => *c += 1,
            None => counts.push((name, 1)),
        }
    }
    counts
        .iter()
        .map(|(n, c)| format!("{c} {n}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The board as lines: slot, serial, mounting, state, points, k2 and K2.
pub fn board_lines(board: &spinbench_engine::board::SlotBoard) -> Vec<String> {
    let pm = |v: f64, u: Option<f64>| match u {
        Some(u) => format!("{v:.3} ± {u:.3}"),
        None => format!("{v:.3}"),
    };
    board
        .slots()
        .iter()
        .map(|s| {
            let phase = s.phase.as_str();
            let k2: Vec<String> = s
                .k2_ug_per_g2
                .iter()
                .map(|(m, v, u)| format!("{m:?} {}", pm(*v, *u)))
                .collect();
            format!(
                "  slot {:>2} {:<14} {:<10} {:>3}/{:<3} pts  k2 {}  K2 {}{}",
                s.slot,
                s.serial,
                phase,
                s.points,
                s.points_planned,
                if k2.is_empty() {
                    "—".into()
                } else {
                    k2.join(", ")
                },
                s.big_k2_ug_per_g2.map_or("—".into(), |(v, u)| pm(v, u)),
                s.outcome.map(|o| format!("  {o}")).unwrap_or_default()
            )
        })
        .collect()
}

/// "T 24.1 °C" or "T 24.1–25.3 °C" for the slots' temperatures, if any came.
fn temperature_range(range: Option<(f64, f64)>) -> String {
    match range {
        None => String::new(),
        Some((lo, hi)) if hi - lo < 0.05 => format!(" | T {lo:.1} °C"),
        Some((lo, hi)) => format!(" | T {lo:.1}–{hi:.1} °C"),
    }
}

impl ProgressPrinter {
    /// What starts a line that replaces the progress line: on a terminal,
    /// back to the start of the line and erase it; into a file or pipe,
    /// nothing (a log holds no escape codes).
    fn clear(&self) -> &'static str {
        if self.tty { "\r\x1b[2K" } else { "" }
    }

    /// A printer (`quiet` prints nothing but faults).
    pub fn new(quiet: bool) -> Self {
        ProgressPrinter {
            tty: std::io::stderr().is_terminal(),
            step: String::new(),
            steps: (0, 0),
            phase: String::new(),
            last: Instant::now(),
            quiet,
            temperatures_c: None,
            board: spinbench_engine::board::SlotBoard::new(),
        }
    }
}

impl EventSink for ProgressPrinter {
    fn emit(&mut self, event: &Event) -> Result<(), spinbench_engine::event::SinkError> {
        let fitted_before: usize = self
            .board
            .slots()
            .iter()
            .map(|s| s.k2_ug_per_g2.len())
            .sum();
        self.board.apply(event);
        let fitted_after: usize = self
            .board
            .slots()
            .iter()
            .map(|s| s.k2_ug_per_g2.len())
            .sum();
        // A pass ended and its k2 were fitted: show every slot.
        if !self.quiet && matches!(event, Event::StepDone { .. }) && fitted_after > fitted_before {
            eprintln!("{}  pass done — the board:", self.clear());
            for line in board_lines(&self.board) {
                eprintln!("{line}");
            }
        }
        match event {
            Event::Fault { reason, .. } => {
                eprintln!(
                    "{}  FAULT: {reason} — bringing the station to the safe state",
                    self.clear()
                )
            }
            _ if self.quiet => {}
            Event::Notice { message, .. } => eprintln!("{}  note: {message}", self.clear()),
            Event::StepStarted {
                index, of, label, ..
            } => {
                self.steps = (*index + 1, *of);
                self.step = label.clone();
                if !self.tty {
                    eprintln!(
                        "  [{:>3}/{}] {label}{}",
                        index + 1,
                        of,
                        temperature_range(self.temperatures_c)
                    );
                }
            }
            Event::Progress { phase, done, of } => self.phase = format!("{phase} {done}/{of}"),
            Event::UnitFailed { slot, reason, .. } => {
                eprintln!("{}  slot {}: FAILED — {reason}", self.clear(), slot + 1)
            }
            Event::Values {
                time_s,
                rate_deg_s,
                on_speed,
                temperatures_c,
                ..
            } => {
                let known = temperatures_c.iter().flatten().copied();
                self.temperatures_c = known.fold(None, |range, t| match range {
                    None => Some((t, t)),
                    Some((lo, hi)) => Some((f64::min(lo, t), f64::max(hi, t))),
                });
                if !self.tty || self.last.elapsed() <= Duration::from_millis(100) {
                    return Ok(());
                }
                self.last = Instant::now();
                let (i, n) = self.steps;
                let bar_len = 20;
                let filled = (i * bar_len).checked_div(n).unwrap_or(0).min(bar_len);
                eprint!(
                    "\r\x1b[2K  [{}{}] {i}/{n} {} | {} | t = {:.0} s | {:.2} deg/s {}{} | {}",
                    "#".repeat(filled),
                    ".".repeat(bar_len - filled),
                    self.step,
                    self.phase,
                    time_s,
                    rate_deg_s,
                    if *on_speed { "on speed" } else { "settling" },
                    temperature_range(self.temperatures_c),
                    phase_counts(&self.board)
                );
            }
            Event::RunFinished { state, reason, .. } => {
                eprintln!(
                    "{}  run {state:?}{}",
                    self.clear(),
                    reason
                        .as_ref()
                        .map(|r| format!(": {r}"))
                        .unwrap_or_default()
                );
            }
            _ => {}
        }
        Ok(())
    }
}
