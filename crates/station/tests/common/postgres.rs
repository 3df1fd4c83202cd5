//! A PostgreSQL server of a test's own (`scripts/postgres`), to restart
//! and pause under a run without disturbing the other tests' server.

#![allow(dead_code)]

use std::path::PathBuf;
use std::process::Command;

/// A throwaway cluster; stopped and removed when dropped.
pub struct Cluster {
    dir: PathBuf,
    /// Its URL.
    pub url: String,
}

fn script() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../scripts/postgres")
}

fn act(action: &str, dir: &PathBuf) -> String {
    let out = Command::new(script())
        .args([action])
        .arg(dir)
        .output()
        .expect("scripts/postgres");
    assert!(
        out.status.success(),
        "scripts/postgres {action}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).trim().to_string()
}

impl Cluster {
    /// A new cluster, or None (with why on stderr) where the suite has no
    /// PostgreSQL (`scripts/test` always has one: SPINBENCH_TEST_POSTGRES).
    pub fn start() -> Option<Cluster> {
        if std::env::var(spinbench_store::testing::POSTGRES_ENV).is_err() {
            eprintln!("skipped: no PostgreSQL (run ./scripts/test)");
            return None;
        }
        let dir = PathBuf::from(
            String::from_utf8_lossy(
                &Command::new("mktemp")
                    .args(["-d", "/tmp/spinbench-pg-outage.XXXXXX"])
                    .output()
                    .expect("mktemp")
                    .stdout,
            )
            .trim(),
        );
        let url = act("start", &dir);
        // Its schema made as `spinbench migrate` makes it (`run` and
        // `serve` never change a PostgreSQL schema).
        let target = spinbench_store::StoreTarget::Postgres(url.clone());
        if let Err(e) = spinbench_store::Store::migrate_target(&target) {
            panic!("{url}: {e}");
        }
        Some(Cluster { dir, url })
    }
    /// A fast restart (the server closes every connection; same port).
    pub fn restart(&self) {
        act("restart", &self.dir);
    }
    /// Every server process stopped (SIGSTOP): it answers nothing.
    pub fn pause(&self) {
        act("pause", &self.dir);
    }
    /// Going on again (SIGCONT).
    pub fn resume(&self) {
        act("resume", &self.dir);
    }
}

impl Drop for Cluster {
    fn drop(&mut self) {
        let _ = Command::new(script()).arg("resume").arg(&self.dir).output();
        let _ = Command::new(script()).arg("stop").arg(&self.dir).output();
    }
}
