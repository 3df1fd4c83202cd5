//! Shared by the station's integration tests.

/// Run the `spinbench` binary with `args`: (succeeded, stdout, stderr).
#[allow(dead_code)] // not every test file runs the binary
pub fn spinbench(args: &[&str]) -> (bool, String, String) {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_spinbench"))
        .args(args)
        .output()
        .expect("run spinbench");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// A short two-mounting plan for the virtual bench (±10 g, 7 levels, no
/// warm-up, 3-s dwell and hold) with instruments `{prefix}1`, `{prefix}2`
/// (module 1) and `{prefix}7` (module 2).
#[allow(dead_code)] // not every test file runs a plan of its own
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

/// The run report `dir` holds for run `id` in format `ext`
/// (`report-<label>-<id>-<language>.<ext>`),
/// English first when both are there.
#[allow(dead_code)] // not every test file reads reports
pub fn report_file(dir: &std::path::Path, id: &str, ext: &str) -> std::path::PathBuf {
    let english = format!("{id}-en.{ext}");
    let found = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .flatten()
        .map(|e| e.path())
        .find(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with("report-") && n.ends_with(&english))
        });
    if let Some(found) = found {
        return found;
    }
    let tail = format!(".{ext}");
    std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .flatten()
        .map(|e| e.path())
        .find(|p| {
            p.file_name().and_then(|n| n.to_str()).is_some_and(|n| {
                n.starts_with("report-") && n.contains(&format!("{id}-")) && n.ends_with(&tail)
            })
        })
        .unwrap_or_else(|| panic!("no report-…{id}-….{ext} in {}", dir.display()))
}

/// The batch report's file of extension `ext` in `dir` (its name carries
/// its runs and language).
#[allow(dead_code)] // not every test file reads batch reports
pub fn batch_file(dir: &std::path::Path, ext: &str) -> std::path::PathBuf {
    std::fs::read_dir(dir)
        .expect("the reports' folder")
        .flatten()
        .map(|e| e.path())
        .find(|p| {
            p.extension().is_some_and(|x| x == ext)
                && p.file_name()
                    .is_some_and(|n| n.to_string_lossy().starts_with("batch-report-"))
        })
        .unwrap_or_else(|| panic!("no batch-report-*.{ext} in {}", dir.display()))
}

/// A role name of one test's own: `prefix` and the fresh database's
/// name in `url`, so tests running at once never share a role.
#[allow(dead_code)] // not every test file makes roles
pub fn role_for(url: &str, prefix: &str) -> String {
    format!(
        "{prefix}_{}",
        url.rsplit('/')
            .next()
            .unwrap_or("x")
            .trim_start_matches("spinbench_test_")
    )
}
