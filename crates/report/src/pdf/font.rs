//! The embedded font (WenQuanYi Micro Hei): parsed once for metrics, and
//! cut down to the glyphs a report uses.

use super::{BTreeSet, FONT_TTC, OnceLock, ParsedFont, ReportError};

/// The embedded font, parsed once per process (metrics for the layout).
pub(super) fn full_font() -> Result<&'static ParsedFont, ReportError> {
    static FONT: OnceLock<Option<ParsedFont>> = OnceLock::new();
    FONT.get_or_init(|| ParsedFont::from_bytes(FONT_TTC, 0, &mut Vec::new()))
        .as_ref()
        .ok_or_else(|| ReportError::Pdf("the embedded font cannot be read".into()))
}

/// The embedded font cut down to the glyphs of `used` (a whole CJK font is
/// 5 MB; a report uses a few hundred glyphs).
pub(super) fn subset_font(
    full: &ParsedFont,
    used: &BTreeSet<char>,
) -> Result<ParsedFont, ReportError> {
    use allsorts::subset::SubsetProfile;
    let fail =
        |what: &str, e: String| ReportError::Pdf(format!("subsetting the font: {what}: {e}"));
    let bytes = subset_bytes(full, used.iter().copied(), SubsetProfile::Pdf)
        .map_err(|e| fail("subset", e.to_string()))?;
    let font = ParsedFont::from_bytes(&bytes, 0, &mut Vec::new())
        .ok_or_else(|| fail("reading the subset", "not a font".into()))?;
    // Every character the full font draws must still map to a glyph.
    if let Some(lost) = used.iter().find(|&&c| {
        full.lookup_glyph_index(c as u32).is_some_and(|g| g != 0)
            && font.lookup_glyph_index(c as u32).is_none_or(|g| g == 0)
    }) {
        return Err(fail("lost a glyph", format!("{lost:?}")));
    }
    Ok(font)
}

/// The embedded font cut down to the characters of `text` as a standalone
/// OpenType font (the Minimal profile: every table a browser requires), for
/// the web UI: a station browser without a CJK font still shows Chinese.
pub fn web_font(text: &str) -> Result<Vec<u8>, ReportError> {
    use allsorts::subset::SubsetProfile;
    subset_bytes(full_font()?, text.chars(), SubsetProfile::Minimal)
        .map_err(|e| ReportError::Pdf(format!("the web font: {e}")))
}

/// Why the embedded font could not be cut to the glyphs a document uses
/// (the font library's words).
#[derive(Debug, thiserror::Error)]
enum SubsetError {
    /// The font collection could not be read.
    #[error("reading: {0}")]
    Read(String),
    /// Its first face could not be read.
    #[error("face 0: {0}")]
    Face(String),
    /// The subsetter refused.
    #[error("{0}")]
    Subset(String),
}

/// The embedded font's glyphs of `chars` as a font of `profile`'s tables.
fn subset_bytes(
    full: &ParsedFont,
    chars: impl Iterator<Item = char>,
    profile: allsorts::subset::SubsetProfile,
) -> Result<Vec<u8>, SubsetError> {
    use allsorts::binary::read::ReadScope;
    use allsorts::font_data::FontData;
    use allsorts::subset::{CmapTarget, subset};
    let mut glyphs: Vec<u16> = chars
        .filter_map(|c| full.lookup_glyph_index(c as u32))
        .filter(|&g| g != 0)
        .collect();
    glyphs.sort_unstable();
    glyphs.dedup();
    // Glyph 0 (.notdef) first, as the subsetter requires.
    let ids: Vec<u16> = std::iter::once(0).chain(glyphs).collect();
    let data = ReadScope::new(FONT_TTC)
        .read::<FontData<'_>>()
        .map_err(|e| SubsetError::Read(e.to_string()))?;
    let provider = data
        .table_provider(0)
        .map_err(|e| SubsetError::Face(e.to_string()))?;
    subset(&provider, &ids, &profile, CmapTarget::Unicode)
        .map_err(|e| SubsetError::Subset(e.to_string()))
}
