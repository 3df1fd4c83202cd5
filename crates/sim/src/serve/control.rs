//! The bench's control socket: remount instruments, read the clock and the
//! truth.

use super::{Mounting, World};

pub(super) fn control_command(world: &mut World, line: &str) -> Option<String> {
    let words: Vec<&str> = line.split_whitespace().collect();
    Some(match words.as_slice() {
        ["MOUNT", who, how] | ["mount", who, how] => match Mounting::parse(how) {
            None => format!("ERR unknown mounting '{how}': UP, DOWN, P or N"),
            Some(m) if who.eq_ignore_ascii_case("ALL") => {
                world.set_all_mountings(m);
                "OK".into()
            }
            Some(m) => match who.parse::<usize>() {
                Ok(i) if i < world.instrument_count() => {
                    world.set_mounting(i, m);
                    "OK".into()
                }
                _ => format!("ERR no instrument '{who}'"),
            },
        },
        ["TIME?"] => format!("{:.4}", world.now_s()),
        ["TRUTH?"] => serde_json::to_string(&world.truth()).unwrap_or_else(|e| format!("ERR {e}")),
        _ => "ERR commands: MOUNT ALL|<index> UP|DOWN|P|N, TIME?, TRUTH?".into(),
    })
}
