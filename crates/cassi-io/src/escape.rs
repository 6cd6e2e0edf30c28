//! Names read from files are shown escaped: a variable name is the file's
//! author's text, and printed raw its control characters (ESC sequences,
//! carriage returns, bidirectional overrides) would act on the user's
//! terminal instead of being seen.

use std::borrow::Cow;

/// Whether `c` must not reach a terminal as it is.
fn dangerous(c: char) -> bool {
    c.is_control()
        || matches!(
            c,
            '\u{061c}' | '\u{200b}'..='\u{200f}' | '\u{2028}'..='\u{202e}' | '\u{2066}'..='\u{2069}' | '\u{feff}'
        )
}

/// `s` with control and text-direction characters written as `\u{1b}`;
/// borrowed when there are none.
pub fn esc(s: &str) -> Cow<'_, str> {
    if !s.chars().any(dangerous) {
        return Cow::Borrowed(s);
    }
    let mut out = String::with_capacity(s.len() + 8);
    for c in s.chars() {
        if dangerous(c) {
            out.extend(c.escape_unicode());
        } else {
            out.push(c);
        }
    }
    Cow::Owned(out)
}

#[cfg(test)]
mod tests {
    use super::esc;

    #[test]
    fn escapes_controls_and_bidi_only() {
        assert_eq!(esc("cube_1"), "cube_1");
        assert_eq!(esc("débit×2"), "débit×2");
        assert_eq!(esc("a\u{1b}[2Jb"), "a\\u{1b}[2Jb");
        assert_eq!(esc("x\ry\n"), "x\\u{d}y\\u{a}");
        assert_eq!(esc("\u{202e}evil"), "\\u{202e}evil");
        assert_eq!(esc("\u{9b}31m"), "\\u{9b}31m");
    }
}
