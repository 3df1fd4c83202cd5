//! The Debian package: cargo-deb packs the binary under
//! test (`--no-build`; `scripts/test` installs cargo-deb), and the package
//! is read back with dpkg-deb: its files, the systemd unit, the conffile,
//! the maintainer scripts with their systemd parts; the packaged binary runs
//! and its packaged station config parses (doctor names its ports as absent).

use std::path::{Path, PathBuf};
use std::process::Command;

fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn text_of(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

#[test]
fn the_debian_package_holds_the_binary_the_unit_and_the_maintainer_scripts() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("deb");
    // The binary the tests run (the dev profile's): no second build.
    let built = Command::new(env!("CARGO"))
        .current_dir(workspace())
        .args([
            "deb",
            "-p",
            "spinbench-station",
            "--no-build",
            "--profile",
            "dev",
            "--no-strip",
            "--fast",
            "--offline",
            "-o",
        ])
        .arg(&out)
        .output()
        .expect("cargo runs");
    assert!(
        built.status.success(),
        "cargo deb failed (scripts/test installs cargo-deb): {}",
        String::from_utf8_lossy(&built.stderr)
    );
    let deb = std::fs::read_dir(&out)
        .expect("the output directory")
        .filter_map(Result::ok)
        .map(|e| e.path())
        .find(|p| p.extension().is_some_and(|e| e == "deb"))
        .expect("a .deb file");
    assert!(
        deb.file_name()
            .and_then(|n| n.to_str())
            .is_some_and(|n| n.starts_with(&format!("spinbench_{}-1_", env!("CARGO_PKG_VERSION")))),
        "{}",
        deb.display()
    );

    // Its files.
    let listing = Command::new("dpkg-deb")
        .arg("-c")
        .arg(&deb)
        .output()
        .expect("dpkg-deb");
    let listing = String::from_utf8_lossy(&listing.stdout).to_string();
    for (file, mode) in [
        ("./usr/bin/spinbench", "-rwxr-xr-x"),
        ("./usr/lib/systemd/system/spinbench.service", "-rw-r--r--"),
        ("./etc/spinbench/station.toml", "-rw-r--r--"),
        ("./etc/default/spinbench", "-rw-r--r--"),
        ("./usr/share/doc/spinbench/README.md", "-rw-r--r--"),
        ("./usr/share/doc/spinbench/copyright", "-rw-r--r--"),
    ] {
        assert!(
            listing
                .lines()
                .any(|l| l.starts_with(mode) && l.ends_with(file)),
            "{file} ({mode}) in\n{listing}"
        );
    }

    // Its control part: name, dependencies, the conffile, the scripts.
    let control = dir.path().join("control");
    let status = Command::new("dpkg-deb")
        .arg("-e")
        .arg(&deb)
        .arg(&control)
        .status()
        .expect("dpkg-deb -e");
    assert!(status.success());
    let fields = text_of(&control.join("control"));
    assert!(fields.contains("Package: spinbench\n"), "{fields}");
    assert!(
        fields
            .lines()
            .any(|l| l.starts_with("Depends:") && l.contains("adduser")),
        "{fields}"
    );
    let conffiles = text_of(&control.join("conffiles"));
    let mut conffiles: Vec<&str> = conffiles.lines().collect();
    conffiles.sort_unstable();
    assert_eq!(
        conffiles,
        ["/etc/default/spinbench", "/etc/spinbench/station.toml"]
    );
    let postinst = text_of(&control.join("postinst"));
    for piece in [
        "adduser --system --group --home /var/lib/spinbench",
        "adduser spinbench dialout",
        "chown spinbench:spinbench /var/lib/spinbench",
        "deb-systemd-helper",
    ] {
        assert!(postinst.contains(piece), "{piece} in postinst:\n{postinst}");
    }
    assert!(
        !postinst.contains("#DEBHELPER#"),
        "the systemd part was put in"
    );
    let postrm = text_of(&control.join("postrm"));
    assert!(postrm.contains("\"purge\"") && postrm.contains("deluser --system spinbench"));
    // The service is stopped before removal.
    let prerm = text_of(&control.join("prerm"));
    assert!(prerm.contains("spinbench.service"), "{prerm}");
    for script in ["postinst", "postrm", "prerm"] {
        let check = Command::new("sh")
            .arg("-n")
            .arg(control.join(script))
            .status()
            .expect("sh -n");
        assert!(check.success(), "{script} is not valid sh");
    }

    // Its files unpacked: the unit runs serve as the spinbench user on the
    // packaged config, and gives a run time to reach its safe state.
    let root = dir.path().join("root");
    let status = Command::new("dpkg-deb")
        .arg("-x")
        .arg(&deb)
        .arg(&root)
        .status()
        .expect("dpkg-deb -x");
    assert!(status.success());
    let unit = text_of(&root.join("usr/lib/systemd/system/spinbench.service"));
    for line in [
        "ExecStart=/usr/bin/spinbench serve --station /etc/spinbench/station.toml --data /var/lib/spinbench $SPINBENCH_SERVE_OPTIONS",
        "EnvironmentFile=-/etc/default/spinbench",
        "EnvironmentFile=-/etc/spinbench/db.env",
        "User=spinbench",
        "SupplementaryGroups=dialout",
        "KillSignal=SIGTERM",
        "WantedBy=multi-user.target",
    ] {
        assert!(
            unit.lines().any(|l| l == line),
            "{line} in the unit:\n{unit}"
        );
    }
    // The unit's exposure, as systemd rates it (offline,
    // on the packaged file), else its hardening lines.
    let unit_path = root.join("usr/lib/systemd/system/spinbench.service");
    let analysed = std::process::Command::new("systemd-analyze")
        .args(["security", "--offline=true"])
        .arg(&unit_path)
        .output();
    match analysed {
        Ok(out) if out.status.success() || !out.stdout.is_empty() => {
            let text = String::from_utf8_lossy(&out.stdout);
            let score: f64 = text
                .lines()
                .find_map(|l| l.split("spinbench.service: ").nth(1))
                .and_then(|rest| rest.split_whitespace().next())
                .and_then(|v| v.parse().ok())
                .unwrap_or_else(|| panic!("no exposure level in:\n{text}"));
            eprintln!("systemd-analyze security: {score}");
            assert!(score <= 2.0, "exposure {score}:\n{text}");
        }
        _ => {
            for line in [
                "CapabilityBoundingSet=",
                "RestrictAddressFamilies=AF_INET AF_INET6 AF_UNIX",
                "SystemCallFilter=@system-service",
                "DevicePolicy=closed",
                "UMask=0027",
                "ProtectKernelTunables=true",
            ] {
                assert!(
                    unit.lines().any(|l| l == line),
                    "{line} in the unit:\n{unit}"
                );
            }
        }
    }
    let defaults = text_of(&root.join("etc/default/spinbench"));
    assert!(
        defaults
            .lines()
            .any(|l| l == "SPINBENCH_SERVE_OPTIONS=\"\""),
        "{defaults}"
    );
    let stop_s: u64 = unit
        .lines()
        .find_map(|l| l.strip_prefix("TimeoutStopSec="))
        .and_then(|v| v.parse().ok())
        .expect("TimeoutStopSec");
    assert!(
        stop_s > 65,
        "a run's safe stop takes up to 60 s + 5 s: {stop_s}"
    );

    // The packaged binary runs; its packaged config parses, and doctor says
    // its example ports are not on this machine.
    let binary = root.join("usr/bin/spinbench");
    let version = Command::new(&binary)
        .arg("--version")
        .output()
        .expect("runs");
    assert!(
        String::from_utf8_lossy(&version.stdout).contains(env!("CARGO_PKG_VERSION")),
        "{version:?}"
    );
    let doctor = Command::new(&binary)
        .args(["doctor", "--station"])
        .arg(root.join("etc/spinbench/station.toml"))
        .arg("--data")
        .arg(dir.path().join("data"))
        .output()
        .expect("doctor");
    let report = String::from_utf8_lossy(&doctor.stdout);
    assert!(!doctor.status.success());
    assert!(report.starts_with("ok    config:"), "{report}");
    assert!(
        report.contains("FAIL  centrifuge (/dev/serial/by-id/usb-centrifuge-controller): the port"),
        "{report}"
    );
}
