//! Parse-error messages that never repeat the content of the file.
//!
//! A command may be pointed at a file that is not ours (`track --calib /etc/shadow`). Parsers'
//! own messages show it: the `toml` crate's `Display` prints the offending source line, and
//! serde's messages quote values (`invalid type: string "...", expected f64`). The helpers here
//! keep what helps (the line, the column, what was expected) and drop the rest: callers report
//! `FILE:LINE:COLUMN: MESSAGE` with the message passed through [`redact_quoted`].

/// A parse error's position (1-based; 0 when unknown) and its message with the quoted values
/// removed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Located {
    pub line: usize,
    pub column: usize,
    pub message: String,
}

/// `:LINE:COLUMN` for a known position, `:LINE` for a line alone, nothing when unknown (0), to
/// follow a file name in a message.
pub fn fmt_position(line: usize, column: usize) -> String {
    match (line, column) {
        (0, _) => String::new(),
        (l, 0) => format!(":{l}"),
        (l, c) => format!(":{l}:{c}"),
    }
}

/// 1-based line and column (counted in characters) of a byte offset in `text`. An offset
/// past the end or inside a character is moved back to the nearest character boundary.
pub fn line_column(text: &str, offset: usize) -> (usize, usize) {
    let mut offset = offset.min(text.len());
    while !text.is_char_boundary(offset) {
        offset -= 1;
    }
    let before = &text[..offset];
    let line = before.bytes().filter(|b| *b == b'\n').count() + 1;
    let start = before.rfind('\n').map_or(0, |i| i + 1);
    let column = before[start..].chars().count() + 1;
    (line, column)
}

/// Whether a back-quoted token is safe to repeat: one of `keep` (the schema's own names) or a
/// short run of punctuation (a grammar's token such as `=` or `]]`).
fn safe_token(token: &str, keep: &[&str]) -> bool {
    keep.contains(&token)
        || (!token.is_empty()
            && token.len() <= 3
            && token.chars().all(|c| c.is_ascii_punctuation()))
}

/// Removes what a parser's message quotes from its input: the content of every `"..."`
/// (backslash escapes included, as serde writes strings with `{:?}`) becomes `...`, and so
/// does that of every `` `...` `` that is not one of `keep` (the field names of the schema,
/// which serde quotes in `missing field `fx``) or a short punctuation token. An unterminated
/// quote hides everything after it.
pub fn redact_quoted(message: &str, keep: &[&str]) -> String {
    let mut out = String::with_capacity(message.len());
    let mut rest = message;
    while let Some(i) = rest.find(['"', '`']) {
        out.push_str(&rest[..i]);
        let quote = rest.as_bytes()[i];
        let after = &rest[i + 1..];
        if quote == b'"' {
            out.push_str("\"...\"");
            // Find the closing quote, skipping backslash escapes.
            let mut end = None;
            let mut escaped = false;
            for (j, c) in after.char_indices() {
                match c {
                    _ if escaped => escaped = false,
                    '\\' => escaped = true,
                    '"' => {
                        end = Some(j);
                        break;
                    }
                    _ => {}
                }
            }
            match end {
                Some(j) => rest = &after[j + 1..],
                None => return out,
            }
        } else {
            match after.find('`') {
                Some(j) => {
                    let token = &after[..j];
                    if safe_token(token, keep) {
                        out.push('`');
                        out.push_str(token);
                        out.push('`');
                    } else {
                        out.push_str("`...`");
                    }
                    rest = &after[j + 1..];
                }
                None => {
                    out.push_str("`...");
                    return out;
                }
            }
        }
    }
    out.push_str(rest);
    out
}

/// A `toml` error as position and redacted message. `text` is the parsed text (the error's
/// span is a byte range into it); `keep` as for [`redact_quoted`].
pub fn toml_error(text: &str, e: &toml::de::Error, keep: &[&str]) -> Located {
    let (line, column) = e.span().map_or((0, 0), |s| line_column(text, s.start));
    Located {
        line,
        column,
        message: redact_quoted(e.message(), keep),
    }
}

/// A `serde_json` error as position and redacted message; `keep` as for [`redact_quoted`].
pub fn json_error(e: &serde_json::Error, keep: &[&str]) -> Located {
    let full = e.to_string();
    let suffix = format!(" at line {} column {}", e.line(), e.column());
    let message = full.strip_suffix(suffix.as_str()).unwrap_or(&full);
    Located {
        line: e.line(),
        column: e.column(),
        message: redact_quoted(message, keep),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn positions_are_one_based_in_characters() {
        let t = "ab\ncdé\nf";
        assert_eq!(line_column(t, 0), (1, 1));
        assert_eq!(line_column(t, 3), (2, 1));
        assert_eq!(line_column(t, 7), (2, 4)); // after the two-byte é
        assert_eq!(line_column(t, 6), (2, 3)); // inside é: moved back to it
        assert_eq!(line_column(t, 100), (3, 2));
        assert_eq!(fmt_position(0, 5), "");
        assert_eq!(fmt_position(3, 0), ":3");
        assert_eq!(fmt_position(3, 4), ":3:4");
    }

    #[test]
    fn quoted_values_are_removed() {
        let keep = ["fx", "intrinsics"];
        assert_eq!(
            redact_quoted("invalid type: string \"SEC\\\"RET\", expected f64", &keep),
            "invalid type: string \"...\", expected f64"
        );
        assert_eq!(
            redact_quoted("missing field `fx`", &keep),
            "missing field `fx`"
        );
        assert_eq!(
            redact_quoted("invalid value: integer `-5`, expected u32", &keep),
            "invalid value: integer `...`, expected u32"
        );
        assert_eq!(
            redact_quoted("unknown field `SECRET`, expected `fx`", &keep),
            "unknown field `...`, expected `fx`"
        );
        assert_eq!(
            redact_quoted("key with no value, expected `=`", &keep),
            "key with no value, expected `=`"
        );
        assert_eq!(redact_quoted("string \"SECRET", &keep), "string \"...\"");
        assert_eq!(redact_quoted("field `SECRET", &keep), "field `...");
    }
}
