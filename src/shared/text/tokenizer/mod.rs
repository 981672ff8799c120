//! OpenAI CLIP's tokenizer, reproduced: `clip/simple_tokenizer.py` (`SimpleTokenizer`) and
//! `clip.tokenize(texts, context_length, truncate=True)`, over a merges file in the format of
//! `bpe_simple_vocab_16e6.txt` (a `#version` header line, then one `left right` merge per line).
//!
//! A prompt goes through, in SimpleTokenizer's order:
//!
//! 1. `basic_clean`: ftfy 6.3.1's `fix_text` with its default configuration (below), then
//!    Python's `html.unescape` twice (HTML5 named references, with and without `;`, the longest
//!    legacy prefix rule, numeric references and their HTML5 replacements), then `str.strip()`.
//! 2. `whitespace_clean`: every run of `\s` (the `regex` module's: Unicode `White_Space`)
//!    becomes one space, then `str.strip()` again (Python's `str.isspace`: `White_Space` plus
//!    U+001C..U+001F), then Python's `str.lower()` (full lowercasing, final sigma included).
//! 3. The split pattern, with IGNORECASE: `<|startoftext|>`, `<|endoftext|>`, the contractions
//!    `'s 't 're 've 'm 'll 'd`, runs of letters `\p{L}+`, single numbers `\p{N}`, and runs of
//!    anything else but whitespace. The `regex` module's IGNORECASE lets `'ſ` (U+017F) match
//!    `'s`, and its `[^\s\p{L}\p{N}]` leaves out U+0345 (which case-folds to a letter), so
//!    U+0345 belongs to no token at all: both are reproduced.
//! 4. Each piece's UTF-8 bytes as `bytes_to_unicode` symbols, the last one with `</w>`; the
//!    merges applied by rank (lowest first, every occurrence left to right, as `bpe` does); the
//!    literal pieces `<|startoftext|>` and `<|endoftext|>` become the special ids.
//!
//! The vocabulary is SimpleTokenizer's: the 256 byte symbols (printable Latin-1 first), the same
//! 256 with `</w>`, one entry per merge, then `<|startoftext|>` and `<|endoftext|>`, so a file
//! of `N` merges gives `512 + N + 2` ids (49,408 for CLIP's 48,894). SimpleTokenizer reads at
//! most 48,894 merges (`49152 - 256 - 2`); a shorter file (the tiny test bundles') is read
//! whole. A file must end without a newline after its last merge: SimpleTokenizer would read the
//! empty line after it as one more (empty) merge and move both special ids by one.
//!
//! # ftfy's `fix_text`
//!
//! Reproduced exactly, per line (ftfy fixes each `\n`-terminated segment on its own and repeats
//! its steps on a segment until they change nothing): `unescape_html` in its "auto" mode (HTML
//! entities ending in `;`, plus ftfy's upper-case forms of the lower-case ones such as `&EACUTE;`;
//! numeric ones only when they decode to something without `;`; switched off for the segment
//! holding the first `<` of the text and for every segment after it, as ftfy's loop keeps the
//! switched-off configuration), `fix_c1_controls` (U+0080..U+009F as Windows-1252, undefined bytes
//! kept), `fix_latin_ligatures`, `fix_character_width` (U+3000 and the NFKC of U+FF01..U+FFEF),
//! `uncurl_quotes`, `fix_line_breaks`, `remove_terminal_escapes`, `remove_control_chars` and the
//! final NFC. `fix_surrogates` has nothing to do: a Rust `&str` holds no surrogate.
//!
//! **Not reproduced**: ftfy's mojibake repair, `fix_encoding` with its subordinate steps
//! `restore_byte_a0`, `replace_lossy_sequences` and `decode_inconsistent_utf8` (and the
//! `fix_c1_controls` it runs inside itself). It is a heuristic: it acts only on a segment that
//! ftfy's `badness.is_bad` flags (sequences such as `Ã©`, `â€™`, `Ð¿Ñ€`, UTF-8 read as Latin-1,
//! Windows-125x or MacRoman), re-encodes it in one of ten single-byte encodings and decodes it
//! as UTF-8. Prompts ftfy would repair this way (mojibake, and rarely ordinary text that its
//! heuristic takes for mojibake) tokenize differently here: we tokenize the text as written.
//!
//! # Other known differences
//!
//! - Python's `int()` refuses decimal strings of more than 4,300 digits, so the reference raises
//!   `ValueError` on a numeric reference such as `&#000…65;` with that many digits; here it
//!   decodes like any other (to U+FFFD once the value is past U+10FFFF).
//! - Unicode versions. Letters and numbers (`\p{L}`, `\p{N}`) are the `regex` module's
//!   (version 2026.11.15, Unicode 18.0): the `regex` crate's classes (Unicode 16.0) plus the
//!   ranges they lack. Lowercasing and `str.isspace` come from Rust's standard library (Unicode
//!   17.0 with rustc 1.95), NFC and NFKC from `unicode-normalization` (Unicode 18.0), while the
//!   reference takes them from its Python's `unicodedata` (Unicode 14.0 in Python 3.11, 15.1 in
//!   3.13): characters encoded after the reference's version may differ. The ones known to:
//!   the 55 capital letters of Unicode 16 and 17 (U+1C89, U+A7CB.., Garay U+10D50..,
//!   U+16EA0..), which Rust lowercases and Python 3.11 leaves as they are.
//!
//! # Limits
//!
//! A prompt is at most [`ClipTokenizer::MAX_PROMPT_BYTES`] bytes of UTF-8 (longer is an error;
//! ftfy's `max_decode_length` of a million characters never applies). The reference is
//! quadratic in two places, and this module is not: SimpleTokenizer's `bpe` rescans a piece after
//! each merge (here a heap makes it `O(n log n)` in the piece's length), and ftfy repeats its
//! whole pass over a line once per level of nested HTML escapes (`&amp;amp;amp;…`), where here
//! the passes after the first re-read only what the previous one changed. The worst 64 KiB
//! prompts take milliseconds (optimised build).

mod ftfy;
mod html;

use std::cmp::Reverse;
use std::collections::{BinaryHeap, HashMap, HashSet};
use std::fmt;
use std::sync::{Mutex, OnceLock};

use regex::Regex;

use self::ftfy::ftfy_fix_text;
use self::html::html_unescape;
use crate::shared::error::{Error, Result};
use crate::shared::limits::{at_most, LIMITS};

/// The special token before a prompt's ids.
const START_OF_TEXT: &str = "<|startoftext|>";
/// The special token after a prompt's ids, the one CLIP's text tower reads.
const END_OF_TEXT: &str = "<|endoftext|>";
/// The suffix of a word's last symbol.
const END_OF_WORD: &str = "</w>";

/// Byte-pair results kept by [`ClipTokenizer`]'s cache before it is emptied.
const CACHE_ENTRIES: usize = 4096;
/// Longest piece, in bytes, whose byte-pair result is cached.
const CACHE_PIECE_BYTES: usize = 48;

/// OpenAI CLIP's byte-pair tokenizer over a merges file: SimpleTokenizer's text cleaning,
/// pieces, vocabulary and merges, and `clip.tokenize`'s padding and truncation. It gives the
/// reference's ids on ordinary Unicode text; it does not reproduce ftfy's mojibake repair
/// (`fix_encoding`), so text such as `cafÃ©` tokenizes as written. The documentation of its
/// module, `src/shared/text/tokenizer/mod.rs`, lists each step and every known difference.
///
/// ```
/// # fn main() -> troupe::Result<()> {
/// // A merges file as CLIP's (no newline after the last merge): 4 merges, 518 ids.
/// let merges = "#version: 0.2\nh e\nl l\nhe ll\nhell o</w>";
/// let tokenizer = troupe::ClipTokenizer::from_merges(merges)?;
/// assert_eq!(tokenizer.vocab_size(), 512 + 4 + 2);
/// assert_eq!(tokenizer.encode(" Hello ")?, vec![515]); // the last merge's symbol, `hello</w>`
/// let row = tokenizer.tokenize("Hello", 5)?;
/// assert_eq!(row, vec![516, 515, 517, 0, 0]); // <|startoftext|> hello <|endoftext|> padding
/// assert_eq!(troupe::ClipTokenizer::end_of_text_index(&row), Some(2));
/// # Ok(())
/// # }
/// ```
///
/// `Send + Sync`: one tokenizer serves any number of threads (its cache is behind a mutex).
pub struct ClipTokenizer {
    /// `(left id, right id)` to `(rank, id of the merged symbol)`.
    merges: HashMap<(u32, u32), (u32, u32)>,
    /// Merges read from the file.
    merge_count: usize,
    /// Id of each byte's symbol.
    byte_ids: [u32; 256],
    /// Id of each byte's symbol with `</w>`.
    byte_end_ids: [u32; 256],
    /// `<|startoftext|>`.
    start: u32,
    /// `<|endoftext|>`.
    end: u32,
    /// Entries of the vocabulary (`512 + merges + 2`).
    vocab_size: usize,
    /// Byte-pair results of short pieces, emptied when it reaches [`CACHE_ENTRIES`].
    cache: Mutex<BpeCache>,
}

/// Byte-pair results by piece.
type BpeCache = HashMap<Box<[u8]>, Box<[u32]>>;

impl fmt::Debug for ClipTokenizer {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("ClipTokenizer")
            .field("merges", &self.merge_count)
            .field("vocab_size", &self.vocab_size)
            .finish_non_exhaustive()
    }
}

impl ClipTokenizer {
    /// Most merges SimpleTokenizer reads from a merges file: `49152 - 256 - 2`.
    ///
    /// cbindgen:ignore
    pub const MAX_MERGES: usize = 49152 - 256 - 2;
    /// Longest prompt [`encode`](Self::encode) and [`tokenize`](Self::tokenize) accept, in bytes
    /// of UTF-8 (CLIP reads 77 tokens, a few hundred characters): `max_prompt_bytes` of
    /// [`LIMITS`].
    ///
    /// cbindgen:ignore
    pub const MAX_PROMPT_BYTES: usize = LIMITS.max_prompt_bytes as usize;

    /// Builds the tokenizer from the text of a merges file: a header line holding `#version`,
    /// then 1 to [`MAX_MERGES`](Self::MAX_MERGES) lines of two symbols separated by whitespace,
    /// each symbol a byte symbol (optionally with `</w>`) or the result of an earlier merge, no
    /// merge twice, and no newline after the last merge. Anything else is an
    /// [`Error::InvalidInput`] naming the line.
    pub fn from_merges(text: &str) -> Result<ClipTokenizer> {
        let bad = |line: usize, what: String| {
            Error::InvalidInput(format!("CLIP merges file, line {line}: {what}"))
        };
        let mut lines = text.split('\n');
        let header = lines.next().unwrap_or_default();
        if !header.contains("#version") {
            return Err(bad(
                1,
                format!(
                    "expected the `#version` header line, found {}",
                    shown(header)
                ),
            ));
        }
        let order = byte_order();
        let mut vocab: Vec<String> = Vec::with_capacity(512 + Self::MAX_MERGES + 2);
        vocab.extend(order.iter().map(|&b| byte_char(b).to_string()));
        vocab.extend(
            order
                .iter()
                .map(|&b| format!("{}{END_OF_WORD}", byte_char(b))),
        );
        let mut known: HashSet<String> = vocab.iter().cloned().collect();
        let mut pairs: Vec<(&str, &str)> = Vec::new();
        let mut seen: HashSet<(&str, &str)> = HashSet::new();
        for (index, line) in lines.enumerate() {
            let number = index + 2;
            if index >= Self::MAX_MERGES {
                return Err(bad(
                    number,
                    format!(
                        "more than {} merges (SimpleTokenizer reads no more)",
                        Self::MAX_MERGES
                    ),
                ));
            }
            let mut parts = line.split(python_isspace).filter(|p| !p.is_empty());
            let (left, right) = match (parts.next(), parts.next(), parts.next()) {
                (Some(left), Some(right), None) => (left, right),
                (None, _, _) => {
                    return Err(bad(
                        number,
                        "empty (a merges file ends without a newline after its last merge: \
                         SimpleTokenizer would read the empty line as a merge)"
                            .into(),
                    ))
                }
                _ => {
                    return Err(bad(
                        number,
                        format!("expected two symbols, found {}", shown(line)),
                    ))
                }
            };
            for symbol in [left, right] {
                if !known.contains(symbol) {
                    return Err(bad(
                        number,
                        format!(
                            "symbol {} is neither a byte symbol nor made by an earlier merge",
                            shown(symbol)
                        ),
                    ));
                }
            }
            if !seen.insert((left, right)) {
                return Err(bad(
                    number,
                    format!("the merge {} {} appears twice", shown(left), shown(right)),
                ));
            }
            let joined = format!("{left}{right}");
            known.insert(joined.clone());
            vocab.push(joined);
            pairs.push((left, right));
        }
        if pairs.is_empty() {
            return Err(bad(2, "no merges after the header".into()));
        }
        vocab.push(START_OF_TEXT.to_owned());
        vocab.push(END_OF_TEXT.to_owned());
        // SimpleTokenizer's `encoder`: a string repeated in the vocabulary maps to its last id.
        let encoder: HashMap<&str, u32> = vocab
            .iter()
            .enumerate()
            .map(|(i, s)| (s.as_str(), i as u32))
            .collect();
        let id = |s: &str| {
            encoder.get(s).copied().ok_or_else(|| {
                Error::InvalidInput(format!("CLIP merges file: {} has no id", shown(s)))
            })
        };
        let mut merges = HashMap::with_capacity(pairs.len());
        for (rank, &(left, right)) in pairs.iter().enumerate() {
            let merged = id(&vocab[512 + rank])?;
            merges.insert((id(left)?, id(right)?), (rank as u32, merged));
        }
        let mut byte_ids = [0u32; 256];
        let mut byte_end_ids = [0u32; 256];
        for b in 0..=255u8 {
            let symbol = byte_char(b).to_string();
            byte_ids[usize::from(b)] = id(&symbol)?;
            byte_end_ids[usize::from(b)] = id(&format!("{symbol}{END_OF_WORD}"))?;
        }
        Ok(ClipTokenizer {
            merge_count: pairs.len(),
            start: id(START_OF_TEXT)?,
            end: id(END_OF_TEXT)?,
            vocab_size: vocab.len(),
            merges,
            byte_ids,
            byte_end_ids,
            cache: Mutex::new(HashMap::new()),
        })
    }

    /// Merges read from the file.
    pub fn merges(&self) -> usize {
        self.merge_count
    }

    /// Entries of the vocabulary: `512 + merges + 2`.
    pub fn vocab_size(&self) -> usize {
        self.vocab_size
    }

    /// The id of `<|startoftext|>` (`512 + merges`).
    pub fn start_of_text(&self) -> u32 {
        self.start
    }

    /// The id of `<|endoftext|>` (`512 + merges + 1`, the largest).
    pub fn end_of_text(&self) -> u32 {
        self.end
    }

    /// SimpleTokenizer's `encode`: the byte-pair ids of `text`, without the special tokens
    /// around it (a literal `<|startoftext|>` or `<|endoftext|>` in the text gives its special
    /// id, as in the reference). Fails only on a text over
    /// [`MAX_PROMPT_BYTES`](Self::MAX_PROMPT_BYTES).
    pub fn encode(&self, text: &str) -> Result<Vec<u32>> {
        at_most(
            "a prompt's length in bytes",
            text.len() as u64,
            Self::MAX_PROMPT_BYTES as u64,
            false,
        )?;
        let cleaned = clean(text);
        let mut ids = Vec::new();
        for piece in split_pattern().find_iter(&cleaned) {
            match piece.as_str() {
                START_OF_TEXT => ids.push(self.start),
                END_OF_TEXT => ids.push(self.end),
                piece => self.bpe_cached(piece.as_bytes(), &mut ids),
            }
        }
        Ok(ids)
    }

    /// `clip.tokenize(text, context, truncate=True)` for one prompt: `<|startoftext|>`, the ids
    /// of [`encode`](Self::encode), `<|endoftext|>`; cut to `context` ids with the last one set
    /// to `<|endoftext|>` when longer, padded with 0 when shorter. `context` is 1 to
    /// `LIMITS.max_text_tokens` (CLIP's 77).
    pub fn tokenize(&self, text: &str, context: usize) -> Result<Vec<i64>> {
        if context == 0 {
            return Err(Error::InvalidInput(
                "a CLIP context of 0 tokens has no room for <|endoftext|>".into(),
            ));
        }
        at_most(
            "the CLIP context",
            context as u64,
            LIMITS.max_text_tokens,
            false,
        )?;
        let ids = self.encode(text)?;
        let mut row = Vec::with_capacity(context.max(ids.len() + 2));
        row.push(i64::from(self.start));
        row.extend(ids.iter().map(|&id| i64::from(id)));
        row.push(i64::from(self.end));
        if row.len() > context {
            row.truncate(context);
            if let Some(last) = row.last_mut() {
                *last = i64::from(self.end);
            }
        }
        row.resize(context, 0);
        Ok(row)
    }

    /// The position CLIP's text tower reads its sentence feature from: `argmax` of the ids, the
    /// first `<|endoftext|>` of a [`tokenize`](Self::tokenize) row (a literal `<|endoftext|>` in
    /// the prompt comes first, as in CLIP). `None` for no ids.
    pub fn end_of_text_index(ids: &[i64]) -> Option<usize> {
        let mut best: Option<(usize, i64)> = None;
        for (i, &id) in ids.iter().enumerate() {
            if best.is_none_or(|(_, max)| id > max) {
                best = Some((i, id));
            }
        }
        best.map(|(i, _)| i)
    }

    /// [`bpe`](Self::bpe) through the bounded cache.
    fn bpe_cached(&self, piece: &[u8], out: &mut Vec<u32>) {
        if piece.len() > CACHE_PIECE_BYTES {
            self.bpe(piece, out);
            return;
        }
        {
            let cache = self.cache.lock().unwrap_or_else(|e| e.into_inner());
            if let Some(ids) = cache.get(piece) {
                out.extend_from_slice(ids);
                return;
            }
        }
        let start = out.len();
        self.bpe(piece, out);
        let mut cache = self.cache.lock().unwrap_or_else(|e| e.into_inner());
        if cache.len() >= CACHE_ENTRIES {
            cache.clear();
        }
        cache.insert(piece.into(), out[start..].into());
    }

    /// SimpleTokenizer's `bpe` on one piece's bytes, appending the ids to `out`.
    ///
    /// The reference repeatedly takes the adjacent pair of lowest rank and merges every
    /// occurrence of it, left to right. Here each adjacent pair with a rank waits in a heap by
    /// `(rank, position)`; one round merges every waiting occurrence of the lowest rank in
    /// position order, skipping those an earlier merge of the round broke up, and only then
    /// queues the pairs the round made (none of which can have the round's rank, since a merged
    /// symbol is longer than either of its parts). That is the reference's order of merges, in
    /// `O(n log n)` instead of its `O(n²)`.
    fn bpe(&self, piece: &[u8], out: &mut Vec<u32>) {
        let n = piece.len();
        let Some((&last, head)) = piece.split_last() else {
            return;
        };
        let mut symbols: Vec<u32> = head
            .iter()
            .map(|&b| self.byte_ids[usize::from(b)])
            .collect();
        symbols.push(self.byte_end_ids[usize::from(last)]);
        if n == 1 {
            out.push(symbols[0]);
            return;
        }
        const NONE: usize = usize::MAX;
        let mut next: Vec<usize> = (1..=n).map(|i| if i < n { i } else { NONE }).collect();
        let mut prev: Vec<usize> = (0..n).map(|i| i.wrapping_sub(1)).collect();
        let mut alive = vec![true; n];
        let rank_at = |symbols: &[u32], next: &[usize], i: usize| -> Option<(u32, u32)> {
            let j = *next.get(i)?;
            let right = *symbols.get(j)?;
            self.merges.get(&(symbols[i], right)).copied()
        };
        let mut heap: BinaryHeap<Reverse<(u32, usize)>> = (0..n - 1)
            .filter_map(|i| rank_at(&symbols, &next, i).map(|(rank, _)| Reverse((rank, i))))
            .collect();
        let mut made: Vec<usize> = Vec::new();
        while let Some(&Reverse((round, _))) = heap.peek() {
            made.clear();
            while let Some(&Reverse((rank, i))) = heap.peek() {
                if rank != round {
                    break;
                }
                heap.pop();
                if !alive[i] {
                    continue;
                }
                let Some((current, merged)) = rank_at(&symbols, &next, i) else {
                    continue;
                };
                if current != rank {
                    continue;
                }
                let j = next[i];
                symbols[i] = merged;
                alive[j] = false;
                next[i] = next[j];
                if next[i] != NONE {
                    prev[next[i]] = i;
                }
                if prev[i] != NONE {
                    made.push(prev[i]);
                }
                made.push(i);
            }
            for &i in &made {
                if alive[i] {
                    if let Some((rank, _)) = rank_at(&symbols, &next, i) {
                        heap.push(Reverse((rank, i)));
                    }
                }
            }
        }
        let mut i = 0;
        while i != NONE {
            out.push(symbols[i]);
            i = next[i];
        }
    }
}

/// Up to 40 characters of `s`, quoted and escaped, for an error message.
fn shown(s: &str) -> String {
    let mut short: String = s.chars().take(40).collect();
    if short.len() < s.len() {
        short.push('…');
    }
    format!("{short:?}")
}

// ------------------------------------------------------------------------------------------------
// Bytes as symbols
// ------------------------------------------------------------------------------------------------

/// Bytes SimpleTokenizer's `bytes_to_unicode` keeps as their own Latin-1 character.
fn printable(b: u8) -> bool {
    matches!(b, b'!'..=b'~' | 0xA1..=0xAC | 0xAE..=0xFF)
}

/// The bytes in vocabulary order: `bytes_to_unicode`'s keys (the printable ones, then the rest
/// in increasing order). A byte's position here is its symbol's id.
fn byte_order() -> [u8; 256] {
    let mut order = [0u8; 256];
    let kept = (0..=255u8).filter(|&b| printable(b));
    let moved = (0..=255u8).filter(|&b| !printable(b));
    for (slot, b) in order.iter_mut().zip(kept.chain(moved)) {
        *slot = b;
    }
    order
}

/// `bytes_to_unicode()[b]`: the byte itself as a Latin-1 character when printable, else the
/// `n`-th character from U+0100 for the `n`-th byte that is not.
fn byte_char(b: u8) -> char {
    if printable(b) {
        return char::from(b);
    }
    let n = (0..b).filter(|&c| !printable(c)).count() as u32;
    char::from_u32(0x100 + n).unwrap_or(char::REPLACEMENT_CHARACTER)
}

// ------------------------------------------------------------------------------------------------
// Text cleaning: basic_clean, whitespace_clean, lower
// ------------------------------------------------------------------------------------------------

/// `whitespace_clean(basic_clean(text)).lower()`.
fn clean(text: &str) -> String {
    let fixed = ftfy_fix_text(text);
    let once = html_unescape(&fixed);
    let twice = html_unescape(&once);
    let collapsed = collapse_whitespace(python_strip(&twice));
    python_strip(&collapsed).to_lowercase()
}

/// Python's `str.isspace`: Unicode `White_Space`, plus U+001C..U+001F.
fn python_isspace(c: char) -> bool {
    c.is_whitespace() || ('\u{1c}'..='\u{1f}').contains(&c)
}

/// Python's `str.strip()`.
fn python_strip(s: &str) -> &str {
    s.trim_matches(python_isspace)
}

/// `regex.sub(r'\s+', ' ', s)` (the `regex` module's `\s` is Unicode `White_Space`).
fn collapse_whitespace(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    let mut in_space = false;
    for c in s.chars() {
        if c.is_whitespace() {
            if !in_space {
                out.push(' ');
            }
            in_space = true;
        } else {
            out.push(c);
            in_space = false;
        }
    }
    out
}

/// Letters of the `regex` module 2026.11.15 (Unicode 18) that the `regex` crate's `\p{L}`
/// (Unicode 16) lacks: code points and ranges in hexadecimal.
const EXTRA_LETTERS: &str =
    "558 58B-58C 88F C5C CDC 208F 209D-209F A7CE-A7CF A7D2 A7D4 A7DD A7E2 A7F1 AB6C-AB6D \
    107BB-107BF 10940-10959 10EC5-10EC7 10ED9-10EEE 11B0A 11DB0-11DDB 11DF1 16EA0-16EB8 \
    16EBB-16ED3 16FF2-16FF3 187F8-187FF 18CD6-18CDA 18D09-18D20 18D80-18DF2 18E00-19191 \
    191A0-191D2 1B123-1B128 1B168 1D6A6 1DF1F-1DF24 1DF2B-1DF81 1DF90-1DF96 1DFCD-1DFFF \
    1E6C0-1E6DE 1E6E0-1E6E2 1E6E4-1E6E5 1E6E7-1E6ED 1E6F0-1E6F4 1E6FE-1E6FF 2B73A-2B73F 2B81E \
    2CEA2-2CEAD 323B0-33479 3D000-3FC3F";

/// Numbers of the `regex` module 2026.11.15 (Unicode 18) that the `regex` crate's `\p{N}` lacks.
const EXTRA_NUMBERS: &str = "11DE0-11DE9 1246F 12475-1247F 12550-12686 16FF4-16FF6";

/// `ranges` (hexadecimal code points and `first-last` ranges) as the inside of a regex class.
fn class_ranges(ranges: &str) -> String {
    ranges
        .split_whitespace()
        .map(|range| {
            range
                .split('-')
                .map(|code| format!(r"\x{{{code}}}"))
                .collect::<Vec<_>>()
                .join("-")
        })
        .collect()
}

/// SimpleTokenizer's `pat` with the `regex` module's semantics: IGNORECASE where it matters
/// (the literals), the letter and number classes of the `regex` module, and U+0345 left out of
/// the last class as the `regex` module's case-insensitive negated class leaves it out.
fn split_pattern() -> &'static Regex {
    static PATTERN: OnceLock<Regex> = OnceLock::new();
    PATTERN.get_or_init(|| {
        let letters = format!(r"\p{{L}}{}", class_ranges(EXTRA_LETTERS));
        let numbers = format!(r"\p{{N}}{}", class_ranges(EXTRA_NUMBERS));
        let pattern = [
            r"(?i:<\|startoftext\|>|<\|endoftext\|>|'s|'t|'re|'ve|'m|'ll|'d)".to_owned(),
            format!("[{letters}]+"),
            format!("[{numbers}]"),
            format!(r"[^\s{letters}{numbers}\x{{345}}]+"),
        ]
        .join("|");
        Regex::new(&pattern).expect("the split pattern is a valid regex")
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A merges file of `merges` (one `left right` per entry) after the header.
    fn merges_file(merges: &[&str]) -> String {
        let mut text = String::from("#version: 0.2");
        for m in merges {
            text.push('\n');
            text.push_str(m);
        }
        text
    }

    fn tokenizer(merges: &[&str]) -> ClipTokenizer {
        ClipTokenizer::from_merges(&merges_file(merges)).unwrap()
    }

    /// The id of a byte's symbol (`end`: with `</w>`).
    fn byte_id(b: u8, end: bool) -> u32 {
        let position = byte_order().iter().position(|&x| x == b).unwrap() as u32;
        position + if end { 256 } else { 0 }
    }

    #[test]
    fn bytes_to_unicode_is_simple_tokenizers() {
        let order = byte_order();
        // The printable bytes first, in order, then the others from 0 up.
        assert_eq!(&order[..3], b"!\"#");
        assert_eq!(order[93], b'~');
        assert_eq!(order[94], 0xA1);
        assert_eq!(order[187], 0xFF);
        assert_eq!(order[188], 0);
        assert_eq!(order[188 + 32], b' ');
        assert_eq!(order[255], 0xAD);
        let mut sorted = order;
        sorted.sort_unstable();
        assert!(sorted.iter().enumerate().all(|(i, &b)| usize::from(b) == i));
        // The characters: the byte itself when printable, else U+0100 onwards.
        assert_eq!(byte_char(b'a'), 'a');
        assert_eq!(byte_char(0xE9), 'é');
        assert_eq!(byte_char(0), '\u{100}');
        assert_eq!(byte_char(b' '), 'Ġ'); // U+0120, GPT-2's well-known space
        assert_eq!(byte_char(0x7F), '\u{121}');
        assert_eq!(byte_char(0xAD), '\u{143}');
        let chars: HashSet<char> = (0..=255u8).map(byte_char).collect();
        assert_eq!(chars.len(), 256);
        assert_eq!(byte_id(b'!', false), 0);
        assert_eq!(byte_id(b'a', true), 256 + 64);
    }

    #[test]
    fn vocabulary_layout_and_special_ids() {
        fn shared<T: Send + Sync>() {}
        shared::<ClipTokenizer>();
        let t = tokenizer(&["h e", "l l", "he ll", "hell o</w>"]);
        assert_eq!(t.merges(), 4);
        assert_eq!(t.vocab_size(), 512 + 4 + 2);
        assert_eq!(t.start_of_text(), 516);
        assert_eq!(t.end_of_text(), 517);
        assert_eq!(t.encode("hello").unwrap(), vec![515]);
        assert_eq!(t.encode("  HELLO\t").unwrap(), vec![515]);
        // Literal special tokens, in any case, give the special ids.
        assert_eq!(
            t.encode("<|startoftext|> <|ENDOFTEXT|>").unwrap(),
            vec![516, 517]
        );
        // Bytes without merges: one symbol each, the last with </w>.
        assert_eq!(
            t.encode("ab").unwrap(),
            vec![byte_id(b'a', false), byte_id(b'b', true)]
        );
        assert_eq!(
            t.encode("é").unwrap(),
            vec![byte_id(0xC3, false), byte_id(0xA9, true)]
        );
        assert_eq!(t.encode("").unwrap(), Vec::<u32>::new());
    }

    #[test]
    fn merges_apply_by_rank_left_to_right() {
        let a = byte_id(b'a', false);
        let d_end = byte_id(b'd', true);
        // The lower rank wins wherever it sits in the word.
        let t = tokenizer(&["b c", "a b"]);
        assert_eq!(t.encode("abcd").unwrap(), vec![a, 512, d_end]);
        let t = tokenizer(&["a b", "b c"]);
        assert_eq!(
            t.encode("abcd").unwrap(),
            vec![512, byte_id(b'c', false), d_end]
        );
        // Overlapping occurrences of one pair merge from the left.
        let t = tokenizer(&["a a"]);
        assert_eq!(t.encode("aaa").unwrap(), vec![512, byte_id(b'a', true)]);
        assert_eq!(
            t.encode("aaaaa").unwrap(),
            vec![512, 512, byte_id(b'a', true)]
        );
        // A merged symbol spelled like a byte symbol takes the later id, as in the reference.
        let t = tokenizer(&["< /", "</ w", "</w >", "a </w>"]);
        assert_eq!(t.encode("a").unwrap(), vec![515]);
    }

    /// SimpleTokenizer's `bpe`, step by step, over ids: the reference for the heap version.
    fn naive_bpe(t: &ClipTokenizer, piece: &[u8]) -> Vec<u32> {
        let (&last, head) = piece.split_last().unwrap();
        let mut word: Vec<u32> = head.iter().map(|&b| t.byte_ids[usize::from(b)]).collect();
        word.push(t.byte_end_ids[usize::from(last)]);
        loop {
            let best = word
                .windows(2)
                .filter_map(|w| {
                    t.merges
                        .get(&(w[0], w[1]))
                        .map(|&(rank, _)| (rank, w[0], w[1]))
                })
                .min();
            let Some((_, first, second)) = best else {
                return word;
            };
            let merged = t.merges[&(first, second)].1;
            let mut next = Vec::with_capacity(word.len());
            let mut i = 0;
            while i < word.len() {
                if i + 1 < word.len() && word[i] == first && word[i + 1] == second {
                    next.push(merged);
                    i += 2;
                } else {
                    next.push(word[i]);
                    i += 1;
                }
            }
            word = next;
        }
    }

    #[test]
    fn heap_bpe_equals_the_reference_algorithm() {
        // Random merges over a three-letter alphabet, each from symbols already known.
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut random = |n: usize| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state % n as u64) as usize
        };
        let mut known: Vec<String> = ["a", "b", "c", "a</w>", "b</w>", "c</w>"]
            .iter()
            .map(|s| s.to_string())
            .collect();
        let mut lines = Vec::new();
        let mut seen = HashSet::new();
        while lines.len() < 60 {
            let (l, r) = (
                known[random(known.len())].clone(),
                known[random(known.len())].clone(),
            );
            if l.ends_with("</w>") || !seen.insert((l.clone(), r.clone())) {
                continue;
            }
            lines.push(format!("{l} {r}"));
            known.push(format!("{l}{r}"));
        }
        let refs: Vec<&str> = lines.iter().map(String::as_str).collect();
        let t = tokenizer(&refs);
        for _ in 0..2000 {
            let len = 1 + random(24);
            let piece: Vec<u8> = (0..len).map(|_| b"abc"[random(3)]).collect();
            let mut ours = Vec::new();
            t.bpe(&piece, &mut ours);
            assert_eq!(
                ours,
                naive_bpe(&t, &piece),
                "{:?}",
                String::from_utf8_lossy(&piece)
            );
        }
    }

    #[test]
    fn tokenize_truncates_and_pads_as_clip() {
        let t = tokenizer(&["h e"]);
        let (sot, eot) = (i64::from(t.start_of_text()), i64::from(t.end_of_text()));
        let (x, y) = (
            i64::from(byte_id(b'x', true)),
            i64::from(byte_id(b'y', true)),
        );
        assert_eq!(t.tokenize("x", 5).unwrap(), vec![sot, x, eot, 0, 0]);
        assert_eq!(t.tokenize("", 4).unwrap(), vec![sot, eot, 0, 0]);
        // Exactly full: no truncation.
        assert_eq!(t.tokenize("x y", 4).unwrap(), vec![sot, x, y, eot]);
        // One too long: cut, the last id made <|endoftext|>.
        assert_eq!(t.tokenize("x y x", 4).unwrap(), vec![sot, x, y, eot]);
        assert_eq!(t.tokenize("x y x y x y", 3).unwrap(), vec![sot, x, eot]);
        assert_eq!(t.tokenize("x", 1).unwrap(), vec![eot]);
        let long = "x ".repeat(500);
        let row = t.tokenize(&long, 77).unwrap();
        assert_eq!(row.len(), 77);
        assert_eq!(row[76], eot);
        assert!(row[1..76].iter().all(|&id| id == x));
        assert_eq!(ClipTokenizer::end_of_text_index(&row), Some(76));
        assert!(t.tokenize("x", 0).is_err());
        assert!(t.tokenize("x", 78).is_err());
    }

    #[test]
    fn end_of_text_index_is_the_first_largest_id() {
        assert_eq!(ClipTokenizer::end_of_text_index(&[]), None);
        assert_eq!(ClipTokenizer::end_of_text_index(&[0, 0]), Some(0));
        assert_eq!(
            ClipTokenizer::end_of_text_index(&[9, 5, 10, 3, 10, 0]),
            Some(2)
        );
    }

    #[test]
    fn prompt_length_is_bounded() {
        let t = tokenizer(&["h e"]);
        let max = ClipTokenizer::MAX_PROMPT_BYTES;
        assert!(t.encode(&"a".repeat(max)).is_ok());
        let err = t.encode(&"a".repeat(max + 1)).unwrap_err();
        assert!(matches!(err, Error::InvalidInput(_)), "{err}");
        assert!(t.tokenize(&"é".repeat(max / 2 + 1), 77).is_err());
    }

    #[test]
    fn malformed_merges_files_are_refused() {
        let refused = |text: &str, needle: &str| {
            let err = ClipTokenizer::from_merges(text).unwrap_err();
            assert!(matches!(err, Error::InvalidInput(_)), "{err}");
            assert!(err.to_string().contains(needle), "{err} lacks {needle:?}");
        };
        refused("", "line 1");
        refused("a b\nc d", "#version");
        refused("#version: 0.2", "no merges");
        refused("#version: 0.2\n", "line 2: empty");
        refused("#version: 0.2\nh e\n", "line 3: empty");
        refused("#version: 0.2\nh e\n\nl l", "line 3: empty");
        refused("#version: 0.2\nh e l", "two symbols");
        refused("#version: 0.2\nhe", "two symbols");
        refused("#version: 0.2\nh e\nhe xy", "\"xy\"");
        refused("#version: 0.2\nl l\nh ell", "\"ell\"");
        refused("#version: 0.2\nh e\nh e", "twice");
        // Symbols built from known pieces, `</w>` ones included, split at any whitespace as
        // Python's str.split() (CRLF line ends included) are fine.
        let t = ClipTokenizer::from_merges("#version: 0.2\nh e\r\nhe\tl\u{a0}\r\nb c</w>\na</w> b");
        assert_eq!(t.unwrap().merges(), 4);
        // More merges than SimpleTokenizer reads.
        let symbols: Vec<String> = (0..=255u8).map(|b| byte_char(b).to_string()).collect();
        let mut text = String::from("#version: 0.2");
        for pair in 0..ClipTokenizer::MAX_MERGES + 1 {
            text.push('\n');
            text.push_str(&symbols[pair / 256]);
            text.push(' ');
            text.push_str(&symbols[pair % 256]);
        }
        refused(&text, "more than 48894 merges");
        let cut = text.rfind('\n').unwrap();
        assert_eq!(
            ClipTokenizer::from_merges(&text[..cut])
                .unwrap()
                .vocab_size(),
            49408
        );
    }

    #[test]
    fn split_pattern_has_the_regex_modules_quirks() {
        let pieces = |text: &str| -> Vec<String> {
            split_pattern()
                .find_iter(&clean(text))
                .map(|m| m.as_str().to_owned())
                .collect()
        };
        assert_eq!(pieces("He's 2 Good!!"), ["he", "'s", "2", "good", "!!"]);
        assert_eq!(pieces("it'ſ"), ["it", "'ſ"]); // IGNORECASE: 'ſ is 's
        assert_eq!(pieces("a\u{345}b"), ["a", "b"]); // U+0345 belongs to no piece
        assert_eq!(pieces("ΟΔΥΣΣΕΥΣ 42"), ["οδυσσευς", "4", "2"]); // final sigma
    }

    #[test]
    fn long_inputs_stay_linear() {
        let t = tokenizer(&["a a", "aa aa", "aaaa aaaa"]);
        // Each hostile shape at `max` bytes, or `max / 16`.
        let cases = |max: usize| {
            [
                format!("&{}", "amp;".repeat((max - 1) / 4)),
                "a".repeat(max),
                "ab".repeat(max / 2),
                "&amp;amp;\n".repeat(max / 10),
                format!("{}{}", "\u{1b}[".repeat(max / 5), "31m".repeat(max / 5)),
                format!(
                    "{}{}",
                    "\u{301}".repeat(max / 4),
                    "&amp;#x301;".repeat(max / 24)
                ),
                // Chains of every depth to 120 after a long run of combining marks: one
                // completes per pass, so the passes are bounded by the depth, not the length.
                format!(
                    "{}{}",
                    "\u{301}".repeat(max / 4),
                    (0..120)
                        .map(|depth| format!("&{}#x301;", "amp;".repeat(depth)))
                        .collect::<String>()
                ),
            ]
        };
        let max = ClipTokenizer::MAX_PROMPT_BYTES;
        let time = |text: &str| {
            let start = std::time::Instant::now();
            t.encode(text).unwrap();
            start.elapsed().as_secs_f64()
        };
        for (i, (small, large)) in cases(max / 16).iter().zip(&cases(max)).enumerate() {
            // The same work done linearly: sixteen inputs a sixteenth as long. Quadratic work
            // takes sixteen times that; the bound allows noise, and any machine's speed (the
            // suite also runs unoptimised and under an emulator).
            let linear: f64 = (0..16).map(|_| time(small)).sum();
            let whole = time(large);
            assert!(
                whole < 6.0 * linear + 0.05,
                "case {i}, {:?}…: {whole:.3} s against {linear:.3} s for 16 sixteenths",
                large.chars().take(20).collect::<String>()
            );
        }
    }
}
