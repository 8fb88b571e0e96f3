//! The deck as tokens: whitespace-separated words with their line and column, and the
//! decimal arithmetic on their text.

/// A whitespace-separated token of the deck and where it starts.
#[derive(Clone, Copy, Debug)]
pub(super) struct Token<'a> {
    pub(super) text: &'a str,
    /// 1-based position in the token stream.
    pub(super) index: usize,
    /// 1-based line.
    pub(super) line: usize,
    /// 1-based column, in characters.
    pub(super) column: usize,
}

/// Splits the deck into tokens on demand, keeping track of lines and columns.
#[derive(Clone)]
pub(super) struct Lexer<'a> {
    pub(super) src: &'a str,
    /// Byte offset of the first unread character.
    pub(super) pos: usize,
    pub(super) line: usize,
    pub(super) column: usize,
    /// Tokens handed out so far.
    pub(super) count: usize,
}

impl<'a> Lexer<'a> {
    pub(super) fn new(src: &'a str) -> Self {
        // A byte-order mark is not part of the first token, and editors do not count it as a
        // column.
        let src = src.strip_prefix('\u{feff}').unwrap_or(src);
        Self { src, pos: 0, line: 1, column: 1, count: 0 }
    }

    /// The next token, or `None` at the end of the deck (then `line`, `column` are the end).
    pub(super) fn next_token(&mut self) -> Option<Token<'a>> {
        let rest = &self.src[self.pos..];
        let blank = rest.find(|c: char| !c.is_whitespace()).unwrap_or(rest.len());
        for c in rest[..blank].chars() {
            if c == '\n' {
                self.line += 1;
                self.column = 1;
            } else {
                self.column += 1;
            }
        }
        self.pos += blank;
        let rest = &self.src[self.pos..];
        if rest.is_empty() {
            return None;
        }
        let len = rest.find(char::is_whitespace).unwrap_or(rest.len());
        let text = &rest[..len];
        self.count += 1;
        let token = Token { text, index: self.count, line: self.line, column: self.column };
        self.column += text.chars().count();
        self.pos += len;
        Some(token)
    }
}

/// The exact difference of two decimal numbers, rounded once to the nearest `f64`; `None`
/// when either is not a plain decimal (`-1.5e-3`) or the exact difference does not fit an
/// `i128` mantissa.
pub(super) fn decimal_difference(a: &str, b: &str) -> Option<f64> {
    let (ma, ea) = decimal(a)?;
    let (mb, eb) = decimal(b)?;
    let e = ea.min(eb);
    let scaled = |m: i128, from: i32| {
        let shift = u32::try_from(from.checked_sub(e)?).ok()?;
        m.checked_mul(10_i128.checked_pow(shift)?)
    };
    let d = scaled(ma, ea)?.checked_sub(scaled(mb, eb)?)?;
    // Rust parses decimal text to the correctly rounded f64.
    format!("{d}e{e}").parse().ok()
}

/// A decimal number `m·10^e` from text such as `-0.0475`, `1.`, `.5` or `2.5E-3`.
fn decimal(text: &str) -> Option<(i128, i32)> {
    let (mantissa, exponent) = match text.find(['e', 'E']) {
        Some(at) => (&text[..at], text[at + 1..].parse::<i32>().ok()?),
        None => (text, 0),
    };
    let (negative, digits) = match mantissa.strip_prefix('-') {
        Some(digits) => (true, digits),
        None => (false, mantissa.strip_prefix('+').unwrap_or(mantissa)),
    };
    let (whole, fraction) = digits.split_once('.').unwrap_or((digits, ""));
    let all_digits = |s: &str| s.bytes().all(|b| b.is_ascii_digit());
    if whole.len() + fraction.len() == 0 || !all_digits(whole) || !all_digits(fraction) {
        return None;
    }
    let significant = format!("{whole}{fraction}");
    let significant = significant.trim_start_matches('0');
    // An i128 holds any 38-digit number; 30 leaves room for aligning two exponents.
    if significant.len() > 30 {
        return None;
    }
    let m: i128 = if significant.is_empty() { 0 } else { significant.parse().ok()? };
    let e = exponent.checked_sub(i32::try_from(fraction.len()).ok()?)?;
    Some((if negative { -m } else { m }, e))
}

/// A token quoted for a message, shortened when long and with control characters escaped.
pub(super) fn shown(text: &str) -> String {
    const MAX_CHARS: usize = 24;
    let mut out: String = text.chars().take(MAX_CHARS).flat_map(char::escape_debug).collect();
    if text.chars().nth(MAX_CHARS).is_some() {
        out.push('…');
    }
    format!("`{out}`")
}
