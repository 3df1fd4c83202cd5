//! The house rules a test can hold: no source file over 700 lines (a file
//! that grows past that holds several rooms and is split by job), and no
//! code comment that cites an issue number a reader of the code does not
//! have.

use std::path::{Path, PathBuf};

/// The longest a source file may be [lines].
const MAX_LINES: usize = 700;

/// Every `.rs` file under each crate's `src/` (tests and benches aside).
fn sources() -> Vec<PathBuf> {
    let crates = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut todo: Vec<PathBuf> = std::fs::read_dir(&crates)
        .expect("the crates folder")
        .filter_map(|e| e.ok().map(|e| e.path().join("src")))
        .filter(|p| p.is_dir())
        .collect();
    let mut files = Vec::new();
    while let Some(dir) = todo.pop() {
        for entry in std::fs::read_dir(&dir).expect("a source folder").flatten() {
            let path = entry.path();
            if path.is_dir() {
                todo.push(path);
            } else if path.extension().is_some_and(|x| x == "rs") {
                files.push(path);
            }
        }
    }
    files.sort();
    files
}

#[test]
fn no_source_file_holds_more_than_one_room() {
    let files = sources();
    assert!(files.len() > 100, "found {} source files", files.len());
    let long: Vec<String> = files
        .iter()
        .filter_map(|f| {
            let lines = std::fs::read_to_string(f)
                .expect("a source file")
                .lines()
                .count();
            (lines > MAX_LINES).then(|| format!("{} ({lines} lines)", f.display()))
        })
        .collect();
    assert!(
        long.is_empty(),
        "over {MAX_LINES} lines, split by job: {long:?}"
    );
}

/// Whether `comment` cites an issue by its number (the word, an optional `#`, digits).
fn cites_an_issue(comment: &str) -> bool {
    let lower = comment.to_ascii_lowercase();
    lower.match_indices("issue").any(|(at, word)| {
        let rest = lower[at + word.len()..].trim_start();
        let rest = rest.strip_prefix('#').unwrap_or(rest);
        rest.starts_with(|c: char| c.is_ascii_digit())
    })
}

#[test]
fn code_comments_say_why_not_which_issue() {
    // The examples are built, so that this file holds no citation itself.
    let (word, n) = ("issue", 52);
    assert!(cites_an_issue(&format!("// see {word} {n}")));
    assert!(cites_an_issue(&format!("/// {word} #{n}: x")));
    assert!(!cites_an_issue("// an issue of the table, 52 levels"));
    let mut cited = Vec::new();
    let crates = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut files = sources();
    for krate in std::fs::read_dir(&crates).expect("crates").flatten() {
        let tests = krate.path().join("tests");
        if let Ok(entries) = std::fs::read_dir(&tests) {
            files.extend(
                entries
                    .flatten()
                    .map(|e| e.path())
                    .filter(|p| p.extension().is_some_and(|x| x == "rs")),
            );
        }
    }
    for f in files {
        let text = std::fs::read_to_string(&f).expect("a source file");
        for (n, line) in text.lines().enumerate() {
            let comment = line.trim_start();
            if comment.starts_with("//") && cites_an_issue(comment) {
                cited.push(format!("{}:{}: {}", f.display(), n + 1, comment));
            }
        }
    }
    assert!(cited.is_empty(), "comments citing issues: {cited:#?}");
}
