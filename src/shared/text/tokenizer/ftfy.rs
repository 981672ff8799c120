//! ftfy 6.3.1's `fix_text` with its default configuration, less `fix_encoding` (the mojibake
//! repair): the first step of SimpleTokenizer's `basic_clean`. What it reproduces, and what it
//! does not, is told in the documentation of the parent module, `tokenizer`.

use std::borrow::Cow;
use std::sync::OnceLock;

use regex::Regex;
use unicode_normalization::char::canonical_combining_class;
use unicode_normalization::{is_nfc_quick, IsNormalized, UnicodeNormalization};

use super::html::{entities, html_unescape, CP1252_C1};

/// `ftfy.fix_text(text)` with the default configuration, less `fix_encoding` (see the
/// documentation of the parent module, `tokenizer`).
pub(super) fn ftfy_fix_text(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut unescape = true;
    for segment in text.split_inclusive('\n') {
        // ftfy's "auto" mode: off from the first segment holding a `<` on (fix_text keeps the
        // configuration it switched off for the segments after it).
        if unescape && segment.contains('<') {
            unescape = false;
        }
        out.push_str(&ftfy_fix_segment(segment, unescape));
    }
    out
}

/// `fix_and_explain` on one segment: the fixers in ftfy's order, repeated until the text stops
/// changing.
///
/// After one pass the text holds nothing the fixers after `unescape_html` act on (no C1
/// control they map, ligature, wide form, curly quote, line break other than `\n`, escape or
/// control character) and is NFC, and their outputs never hold such characters either (a unit
/// test checks every character), so a further pass
/// changes the text only where `unescape_html` replaces an entity, and only around it. The
/// later passes ([`later_passes`]) therefore re-read only what the previous one changed: ftfy's
/// result, without its pass over the whole line per level of nested escapes.
fn ftfy_fix_segment(segment: &str, unescape: bool) -> String {
    let Some(mut text) = full_pass(segment, unescape) else {
        return segment.to_owned();
    };
    if unescape {
        return later_passes(text);
    }
    // Without `unescape_html` the second pass changes nothing; run the passes regardless, with
    // a bound that only guarantees an end.
    for _ in 0..segment.len() + 4 {
        match full_pass(&text, false) {
            Some(fixed) => text = fixed,
            None => break,
        }
    }
    text
}

/// One pass of ftfy's fixers over `text` (`None`: it changes nothing).
fn full_pass(text: &str, unescape: bool) -> Option<String> {
    let mut pass = Cow::Borrowed(text);
    if unescape {
        apply(&mut pass, ftfy_unescape_html);
    }
    if let Some(fixed) = after_unescape(&pass) {
        pass = Cow::Owned(fixed);
    }
    match pass {
        Cow::Owned(fixed) if fixed != text => Some(fixed),
        _ => None,
    }
}

/// The fixers after `unescape_html`, in ftfy's order, then NFC (`None`: they change nothing).
fn after_unescape(text: &str) -> Option<String> {
    let mut pass = Cow::Borrowed(text);
    apply(&mut pass, fix_c1_controls);
    apply(&mut pass, fix_latin_ligatures);
    apply(&mut pass, fix_character_width);
    apply(&mut pass, uncurl_quotes);
    apply(&mut pass, fix_line_breaks);
    apply(&mut pass, remove_terminal_escapes);
    apply(&mut pass, remove_control_chars);
    apply(&mut pass, normalize_nfc);
    match pass {
        Cow::Owned(fixed) => Some(fixed),
        Cow::Borrowed(_) => None,
    }
}

/// Bytes an entity can reach past its `&`: `#`, 24 letters or digits, `;`.
const ENTITY_REACH: usize = 26;

/// ftfy's passes after the first over a text one pass has fixed: each replaces the entities
/// `unescape_html` finds and runs the other fixers over a window around each replacement, whose
/// edges are characters no fixer changes and NFC does not combine across. An `&` is looked at
/// again only when the previous pass changed something within its reach.
fn later_passes(mut text: String) -> String {
    let mut candidates: Vec<usize> = ampersands(&text, 0, text.len());
    // Each pass that changes the text shortens it; the bound only guarantees an end.
    for _ in 0..text.len() + 4 {
        let mut edits: Vec<(usize, usize, String)> = Vec::new();
        for &at in &candidates {
            if let Some((len, value)) = ftfy_entity_at(&text, at) {
                edits.push((at, at + len, value.into_owned()));
            }
        }
        if edits.is_empty() {
            break;
        }
        // Where each replacement lands once all of them are made.
        let mut shift = 0isize;
        let mut inserted = Vec::with_capacity(edits.len());
        for (start, end, value) in &edits {
            let at = start.wrapping_add_signed(shift);
            inserted.push((at, at + value.len()));
            shift += value.len() as isize - (end - start) as isize;
        }
        for (start, end, value) in edits.iter().rev() {
            text.replace_range(start..end, value);
        }
        // The windows around them, merged where they touch; no byte is scanned twice.
        let mut windows: Vec<(usize, usize)> = Vec::new();
        for &(from, to) in &inserted {
            let floor = windows.last().map_or(0, |w| w.1);
            let left = if from < floor {
                floor
            } else {
                window_start(&text, from, floor)
            };
            match windows.last_mut() {
                Some(last) if left <= last.1 => last.1 = window_end(&text, to.max(last.1)),
                _ => windows.push((left, window_end(&text, to))),
            }
        }
        let mut changed = Vec::with_capacity(windows.len());
        let mut shift = 0isize;
        let mut fixed_windows = Vec::with_capacity(windows.len());
        for &(left, right) in &windows {
            let fixed = after_unescape(&text[left..right]);
            let len = fixed.as_ref().map_or(right - left, String::len);
            let at = left.wrapping_add_signed(shift);
            changed.push((at, at + len));
            shift += len as isize - (right - left) as isize;
            fixed_windows.push(fixed);
        }
        for (&(left, right), fixed) in windows.iter().zip(&fixed_windows).rev() {
            if let Some(fixed) = fixed {
                text.replace_range(left..right, fixed);
            }
        }
        candidates.clear();
        for &(from, to) in &changed {
            candidates.extend(ampersands(&text, from.saturating_sub(ENTITY_REACH), to));
        }
        candidates.sort_unstable();
        candidates.dedup();
    }
    text
}

/// Byte positions of the `&`s starting in `text[from..to]` (`&` is never part of another
/// character's UTF-8).
fn ampersands(text: &str, from: usize, to: usize) -> Vec<usize> {
    let bytes = &text.as_bytes()[from.min(text.len())..to.min(text.len())];
    bytes
        .iter()
        .enumerate()
        .filter(|&(_, &b)| b == b'&')
        .map(|(i, _)| from + i)
        .collect()
}

/// Whether a window of the later passes may start or end just before `c`: a character no fixer
/// after `unescape_html` changes, and an NFC starter nothing before it can combine with.
fn stable_starter(c: char) -> bool {
    if c.is_ascii() {
        return matches!(c, ' '..='~' | '\t' | '\n' | '\u{c}');
    }
    let fixed = matches!(c,
        '\u{80}'..='\u{9f}' | 'Ĳ' | 'ĳ' | 'ŉ' | '\u{1c4}'..='\u{1cc}' | '\u{1f1}'..='\u{1f3}' | 'ﬀ'..='ﬆ' | '\u{3000}'
        | '\u{ff01}'..='\u{ffef}' | '\u{2bc}' | '\u{2018}'..='\u{201f}' | '\u{2028}'
        | '\u{2029}' | '\u{206a}'..='\u{206f}' | '\u{feff}' | '\u{fff9}'..='\u{fffc}');
    !fixed
        && canonical_combining_class(c) == 0
        && is_nfc_quick(std::iter::once(c)) == IsNormalized::Yes
}

/// Whether a window may have an edge at byte `at` of `text`: its start or end, or before a
/// [`stable_starter`] that does not follow a `\r` (which would pair with a `\n`).
fn window_edge(text: &str, at: usize) -> bool {
    if at == 0 || at >= text.len() {
        return true;
    }
    let before = text[..at].chars().next_back();
    let after = text[at..].chars().next();
    before != Some('\r') && after.is_some_and(stable_starter)
}

/// The last window edge at or before byte `at`, or `floor` (the end of the window before).
fn window_start(text: &str, at: usize, floor: usize) -> usize {
    let mut at = at;
    while at > floor && !window_edge(text, at) {
        at -= text[..at].chars().next_back().map_or(1, char::len_utf8);
    }
    at
}

/// The first window edge at or after byte `at`.
fn window_end(text: &str, at: usize) -> usize {
    let mut at = at;
    while !window_edge(text, at) {
        at += text[at..].chars().next().map_or(1, char::len_utf8);
    }
    at
}

/// Replaces `text` with `fix(text)` when that changes it (`None`: unchanged).
fn apply(text: &mut Cow<'_, str>, fix: fn(&str) -> Option<String>) {
    if let Some(fixed) = fix(text) {
        *text = Cow::Owned(fixed);
    }
}

/// `str.translate` with `map` (`None`: keep the character), or `None` when no character maps.
fn translate(text: &str, map: impl Fn(char) -> Option<&'static str>) -> Option<String> {
    let first = text.char_indices().find(|&(_, c)| map(c).is_some())?.0;
    let mut out = String::with_capacity(text.len() + 8);
    out.push_str(&text[..first]);
    for c in text[first..].chars() {
        match map(c) {
            Some(s) => out.push_str(s),
            None => out.push(c),
        }
    }
    Some(out)
}

/// `fix_c1_controls`: U+0080..U+009F as their Windows-1252 characters.
fn fix_c1_controls(text: &str) -> Option<String> {
    let changes = |c: char| matches!(u32::from(c), code @ 0x80..=0x9F if CP1252_C1[(code - 0x80) as usize] != c);
    if text.is_ascii() || !text.chars().any(changes) {
        return None;
    }
    Some(
        text.chars()
            .map(|c| match u32::from(c) {
                code @ 0x80..=0x9F => CP1252_C1[(code - 0x80) as usize],
                _ => c,
            })
            .collect(),
    )
}

/// `fix_latin_ligatures`: ftfy's `LIGATURES`.
fn fix_latin_ligatures(text: &str) -> Option<String> {
    if text.is_ascii() {
        return None;
    }
    translate(text, |c| {
        Some(match c {
            'Ĳ' => "IJ",
            'ĳ' => "ij",
            'ŉ' => "ʼn",
            'Ǳ' => "DZ",
            'ǲ' => "Dz",
            'ǳ' => "dz",
            'Ǆ' => "DŽ",
            'ǅ' => "Dž",
            'ǆ' => "dž",
            'Ǉ' => "LJ",
            'ǈ' => "Lj",
            'ǉ' => "lj",
            'Ǌ' => "NJ",
            'ǋ' => "Nj",
            'ǌ' => "nj",
            'ﬀ' => "ff",
            'ﬁ' => "fi",
            'ﬂ' => "fl",
            'ﬃ' => "ffi",
            'ﬄ' => "ffl",
            'ﬅ' => "ſt",
            'ﬆ' => "st",
            _ => return None,
        })
    })
}

/// `fix_character_width`: U+3000 as a space, U+FF01..U+FFEF as their NFKC form.
fn fix_character_width(text: &str) -> Option<String> {
    let narrow = |c: char| -> Option<String> {
        if c == '\u{3000}' {
            return Some(" ".into());
        }
        if !('\u{ff01}'..='\u{ffef}').contains(&c) {
            return None;
        }
        let form: String = std::iter::once(c).nfkc().collect();
        (form.chars().ne(std::iter::once(c))).then_some(form)
    };
    if text.is_ascii() || !text.chars().any(|c| narrow(c).is_some()) {
        return None;
    }
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match narrow(c) {
            Some(form) => out.push_str(&form),
            None => out.push(c),
        }
    }
    Some(out)
}

/// `uncurl_quotes`: U+02BC and U+2018..U+201B as `'`, U+201C..U+201F as `"`.
fn uncurl_quotes(text: &str) -> Option<String> {
    if text.is_ascii() {
        return None;
    }
    translate(text, |c| match c {
        '\u{2bc}' | '\u{2018}'..='\u{201b}' => Some("'"),
        '\u{201c}'..='\u{201f}' => Some("\""),
        _ => None,
    })
}

/// `fix_line_breaks`: CRLF, CR, U+2028, U+2029 and U+0085 as `\n`, in ftfy's order.
fn fix_line_breaks(text: &str) -> Option<String> {
    let breaks = |c: char| matches!(c, '\r' | '\u{2028}' | '\u{2029}' | '\u{85}');
    if !text.contains(breaks) {
        return None;
    }
    Some(
        text.replace("\r\n", "\n")
            .replace(['\r', '\u{2028}', '\u{2029}', '\u{85}'], "\n"),
    )
}

/// `remove_terminal_escapes`: `ESC [ (digits or ;)* letter`, with Python's Unicode `\d`.
fn remove_terminal_escapes(text: &str) -> Option<String> {
    static ANSI: OnceLock<Regex> = OnceLock::new();
    if !text.contains('\u{1b}') {
        return None;
    }
    let ansi = ANSI.get_or_init(|| {
        Regex::new(r"\x1b\[[\d;]*[a-zA-Z]").expect("the escape pattern is a valid regex")
    });
    match ansi.replace_all(text, "") {
        Cow::Borrowed(_) => None,
        Cow::Owned(fixed) => Some(fixed),
    }
}

/// `remove_control_chars`: ftfy's `CONTROL_CHARS` (C0 controls but tab, line feed, form feed
/// and carriage return; DEL; U+206A..U+206F; U+FEFF; U+FFF9..U+FFFC).
fn remove_control_chars(text: &str) -> Option<String> {
    let control = |c: char| {
        matches!(
            c,
            '\u{0}'..='\u{8}'
                | '\u{b}'
                | '\u{e}'..='\u{1f}'
                | '\u{7f}'
                | '\u{206a}'..='\u{206f}'
                | '\u{feff}'
                | '\u{fff9}'..='\u{fffc}'
        )
    };
    if !text.contains(control) {
        return None;
    }
    Some(text.chars().filter(|&c| !control(c)).collect())
}

/// Unicode NFC.
fn normalize_nfc(text: &str) -> Option<String> {
    if text.is_ascii() || is_nfc_quick(text.chars()) == IsNormalized::Yes {
        return None;
    }
    let fixed: String = text.nfc().collect();
    (fixed != text).then_some(fixed)
}

/// ftfy's `unescape_html`: each `&#?[0-9A-Za-z]{1,24};` that is one of ftfy's `HTML_ENTITIES`
/// becomes its text; a numeric one becomes what `html.unescape` makes of it when that holds no
/// `;` (so all of it was read); anything else stays.
fn ftfy_unescape_html(text: &str) -> Option<String> {
    if !text.contains('&') {
        return None;
    }
    let mut out = String::with_capacity(text.len());
    let mut changed = false;
    let mut done = 0;
    for at in ampersands(text, 0, text.len()) {
        if at < done {
            continue;
        }
        if let Some((len, value)) = ftfy_entity_at(text, at) {
            out.push_str(&text[done..at]);
            out.push_str(&value);
            done = at + len;
            changed = true;
        }
    }
    out.push_str(&text[done..]);
    changed.then_some(out)
}

/// The entity ftfy's `unescape_html` replaces at the `&` at byte `at` of `text`: its length in
/// bytes and its replacement, or `None` when it leaves this `&` alone. A match holds no other `&`,
/// so each `&` is decided on its own.
fn ftfy_entity_at(text: &str, at: usize) -> Option<(usize, Cow<'static, str>)> {
    let after = text.get(at + 1..)?;
    let hash = after.starts_with('#');
    let body = &after[usize::from(hash)..];
    let run = body
        .bytes()
        .take_while(|b| b.is_ascii_alphanumeric())
        .count();
    if !(1..=24).contains(&run) || body.as_bytes().get(run) != Some(&b';') {
        return None;
    }
    let len = 1 + usize::from(hash) + run + 1;
    if hash {
        let decoded = html_unescape(&text[at..at + len]);
        if decoded.contains(';') {
            return None;
        }
        return Some((len, Cow::Owned(decoded.into_owned())));
    }
    let value = entities().ftfy.get(&body[..run])?;
    Some((len, Cow::Borrowed(value.as_str())))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ftfy_steps() {
        // Ligatures, width, quotes, C1 controls, line breaks, escapes, control characters, NFC.
        assert_eq!(ftfy_fix_text("ﬂuﬃeﬆ"), "fluffiest");
        assert_eq!(
            ftfy_fix_text("ＬＯＵＤ　ＮＯＩＳＥＳ ｶﾞ"),
            "LOUD NOISES ｶﾞ".replace("ｶﾞ", "ガ")
        );
        assert_eq!(ftfy_fix_text("\u{201c}here\u{2019}s\u{201d}"), "\"here's\"");
        assert_eq!(ftfy_fix_text("\u{80}5 \u{85}"), "€5 …");
        assert_eq!(ftfy_fix_text("a\r\nb\rc\u{2028}d"), "a\nb\nc\nd");
        assert_eq!(ftfy_fix_text("\u{1b}[36;44mblue\u{1b}[0m"), "blue");
        assert_eq!(ftfy_fix_text("a\u{0}b\u{feff}c\u{7f}\td"), "abc\td");
        assert_eq!(ftfy_fix_text("cafe\u{301}"), "café");
        // Entities: named, upper-case, numeric, nested; not `&#59;` (it decodes to `;`).
        assert_eq!(
            ftfy_fix_text("P&EACUTE;REZ &amp;amp; &#x2019;&#59;"),
            "PÉREZ & '&#59;"
        );
        assert_eq!(
            ftfy_fix_text("BUNDESSTRA&SZLIG;E &nTILDE;"),
            "BUNDESSTRASSE &nTILDE;"
        );
        // A `<` switches unescaping off for its line and every line after it.
        assert_eq!(
            ftfy_fix_text("&amp;\n<b>&amp;\n&amp;"),
            "&\n<b>&amp;\n&amp;"
        );
        assert_eq!(ftfy_fix_text("&amp;lt;b&amp;gt;"), "<b>");
    }

    /// The later passes re-read only what changed: the result must be that of whole passes.
    #[test]
    fn later_passes_equal_whole_passes() {
        let whole = |segment: &str| {
            let mut text = segment.to_owned();
            while let Some(fixed) = full_pass(&text, true) {
                text = fixed;
            }
            text
        };
        let nested = |depth: usize, tail: &str| format!("&{}{tail}", "amp;".repeat(depth));
        let cases = [
            format!("e{}", nested(3, "#x301;")),
            format!("가{}b", nested(2, "#x11A8;")),
            format!("{}\n", nested(4, "#13;")),
            format!("x{}{}y", nested(2, "#xFEFF;"), nested(1, "#x301;")),
            format!("{}{}", nested(5, "lt"), nested(2, "semi;")),
            format!("&amp{}", nested(3, "semi;")),
            format!("\u{301}{}\u{301}", nested(6, "ffilig;")),
            format!("a{}\u{345}", nested(2, "#x37e;")),
            format!("{}{}", "字".repeat(50), nested(40, "#x344;")),
        ];
        for case in &cases {
            let first = full_pass(case, true).unwrap_or_else(|| case.clone());
            assert_eq!(later_passes(first), whole(case), "{case:?}");
        }
    }

    /// `later_passes` assumes one pass leaves nothing for the fixers after `unescape_html`: NFC
    /// never makes a character they change, and they are idempotent on every character.
    #[test]
    fn fixers_after_unescape_are_idempotent() {
        for code in 0..=0x10FFFFu32 {
            let Some(c) = char::from_u32(code) else {
                continue;
            };
            let mut buffer = [0u8; 4];
            if let Some(once) = after_unescape(c.encode_utf8(&mut buffer)) {
                assert_eq!(after_unescape(&once), None, "U+{code:04X}");
            }
        }
    }
}
