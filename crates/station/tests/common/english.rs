//! Finding English in a text meant to be Chinese: shared by
//! the report and the page tests.

/// Words of Latin letters that stand in a Chinese report or page: units,
/// symbols and names that are the same in every language.
pub const SAME_IN_EVERY_LANGUAGE: &[&str] = &[
    "spinbench", // the software's name
    "English",   // the language menu names each language in its own words
    "docs",
    "method",
    "md", // the method document's path, docs/method.md
    "max",
    "min", // k2_max, indices
    "deg", // deg/s
    "ppm",
    "rms",
    "RMS",
    "GUM",
    "ISO",
    "ILAC",
    "UTC",
    "IEEE",
    "Hz",
    "dF",  // the output's symbol
    "ref", // T_ref
    "Koq", // the odd coefficient of the model (method (15))
    "now", // the curves' time axis ends at "now" (a symbol of the plot)
];

/// The English words in `text` once `data` (the run's own names, which no
/// language changes) is taken out: every word of three or more Latin
/// letters with a lower-case letter that is not the same in every
/// language, with the line it stands in.
pub fn english_words(text: &str, data: &[String]) -> Vec<String> {
    let mut text = text.to_string();
    for d in data {
        text = text.replace(d.as_str(), " ");
    }
    let mut found = Vec::new();
    for line in text.lines() {
        for word in line.split(|c: char| !c.is_ascii_alphabetic()) {
            if word.len() >= 3
                && word.chars().any(|c| c.is_ascii_lowercase())
                && !SAME_IN_EVERY_LANGUAGE.contains(&word)
            {
                found.push(format!("{word}  ← {}", line.trim()));
            }
        }
    }
    found
}
