//! The shot format's version and its keys: a shot never ignores what it does not understand.
//!
//! Before the shot is read into its types, the TOML document is walked with the spans of its
//! keys, and every key must be one that this version of the format knows, table by table
//! ([`KNOWN_KEYS`]). A misspelt or newer key (`[placment]`, `yaw_degs`, `[marker] picture`) is
//! refused with its dotted name, its line and column, and the format the file claims (the
//! optional top-level `format = N`; a file without it is format 1). A file written for a
//! newer format than [`SHOT_FORMAT`] is refused as such, before its keys are looked at.
//!
//! A new section or key is one edit: its row (or its name in a row) in [`KNOWN_KEYS`], and
//! the top level's row for a new section.

use std::path::Path;

use pa_camera::diag::line_column;
use toml::de::{DeTable, DeValue};
use toml::Spanned;

use super::ShotError;

/// The shot format this version of Props Alive reads and writes.
pub const SHOT_FORMAT: u32 = 1;

/// The keys each table of a shot may hold, by the table's dotted path (`""` is the top level;
/// an array of tables such as `[[key_poses]]` is one path for all its entries). A key whose
/// value is a table or an array of tables is checked inside only when its path has a row.
pub const KNOWN_KEYS: &[(&str, &[&str])] = &[
    (
        "",
        &[
            "format",
            "model",
            "animation",
            "fps",
            "present_key",
            "key_poses",
            "camera",
            "marker",
            "placement",
            "diminish",
            "scan",
            "texture",
        ],
    ),
    ("key_poses", &["name", "frame", "marker_id"]),
    ("scan", &["input"]),
    ("texture", &["relight", "feather", "sun", "grazing"]),
    ("camera", &["calibration", "fov_y_deg"]),
    (
        "marker",
        &["family", "tags", "image", "width_m", "hide", "cover"],
    ),
    ("marker.tags", &["id", "center_m", "size_m"]),
    (
        "placement",
        &["translation_m", "upright", "yaw_deg", "scale"],
    ),
    (
        "diminish",
        &[
            "fill",
            "clean_plate",
            "plate_frames",
            "dilation_px",
            "shadows",
            "align_plate",
        ],
    ),
];

/// Every key name of [`KNOWN_KEYS`] (which parse errors may repeat).
pub fn field_names() -> Vec<&'static str> {
    let mut names: Vec<&'static str> = KNOWN_KEYS
        .iter()
        .flat_map(|(table, keys)| table.split('.').chain(keys.iter().copied()))
        .filter(|k| !k.is_empty())
        .collect();
    names.sort_unstable();
    names.dedup();
    names
}

/// The row of [`KNOWN_KEYS`] of the table at `path`.
fn row(path: &str) -> Option<(&'static str, &'static [&'static str])> {
    KNOWN_KEYS.iter().find(|(table, _)| *table == path).copied()
}

/// A key name that may be repeated in a message: short, and only the characters of a TOML
/// bare key (the file may not be a shot at all; its content is not echoed).
fn printable(key: &str) -> bool {
    !key.is_empty()
        && key.len() <= 64
        && key
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
}

/// Edit distance of two short names: insertions, deletions, substitutions and swaps of two
/// neighbouring letters (`modle`), each 1 (optimal string alignment).
fn distance(a: &str, b: &str) -> usize {
    let a: Vec<char> = a.chars().collect();
    let b: Vec<char> = b.chars().collect();
    let w = b.len() + 1;
    let mut d = vec![0usize; (a.len() + 1) * w];
    for i in 0..=a.len() {
        for j in 0..=b.len() {
            d[i * w + j] = if i == 0 || j == 0 {
                i + j
            } else {
                let mut best = (d[(i - 1) * w + j - 1] + usize::from(a[i - 1] != b[j - 1]))
                    .min(d[(i - 1) * w + j] + 1)
                    .min(d[i * w + j - 1] + 1);
                if i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1] {
                    best = best.min(d[(i - 2) * w + j - 2] + 1);
                }
                best
            };
        }
    }
    d[a.len() * w + b.len()]
}

/// The known key closest to `key` when it is a likely misspelling (at most a third of its
/// letters differ, or one is the other with a suffix such as `yaw_degs`).
fn suggestion(key: &str, known: &[&'static str]) -> Option<&'static str> {
    known
        .iter()
        .map(|k| (distance(key, k), *k))
        .filter(|(d, k)| *d <= (k.len() / 3).max(1) || key.starts_with(k) || k.starts_with(key))
        .min_by_key(|(d, _)| *d)
        .map(|(_, k)| k)
}

/// The format a shot claims and the check of its keys: parses `text` (a TOML syntax error is
/// left to the caller's full parse, which reports it), refuses a format other than
/// [`SHOT_FORMAT`] and any key the format does not know. Returns the format.
pub fn check_keys(text: &str, path: &Path) -> Result<u32, ShotError> {
    let Ok(doc) = DeTable::parse(text) else {
        return Ok(SHOT_FORMAT);
    };
    let format = claimed_format(text, path, doc.get_ref())?;
    walk(text, path, format, "", doc.get_ref())?;
    Ok(format)
}

/// The top-level `format`: absent means 1; it must be a whole number from 1 to
/// [`SHOT_FORMAT`].
fn claimed_format(text: &str, path: &Path, doc: &DeTable<'_>) -> Result<u32, ShotError> {
    let Some((key, value)) = doc.iter().find(|(k, _)| k.get_ref() == "format") else {
        return Ok(SHOT_FORMAT);
    };
    let (line, column) = line_column(text, key.span().start);
    let number = match value.get_ref() {
        DeValue::Integer(i) => i64::from_str_radix(i.as_str(), i.radix()).ok(),
        _ => None,
    };
    match number {
        Some(n) if n >= 1 && n <= i64::from(SHOT_FORMAT) => Ok(n as u32),
        Some(n) if n > i64::from(SHOT_FORMAT) => Err(ShotError::NewerFormat {
            path: path.into(),
            line,
            column,
            format: n,
        }),
        _ => Err(ShotError::Parse {
            path: path.into(),
            line,
            column,
            message: format!(
                "`format` is the shot format's version, a whole number from 1 to {SHOT_FORMAT}"
            ),
        }),
    }
}

fn walk(
    text: &str,
    path: &Path,
    format: u32,
    table: &str,
    entries: &DeTable<'_>,
) -> Result<(), ShotError> {
    let Some((table, keys)) = row(table) else {
        return Ok(());
    };
    for (key, value) in entries.iter() {
        let name = key.get_ref().as_ref();
        let dotted = if table.is_empty() {
            name.to_string()
        } else {
            format!("{table}.{name}")
        };
        if !keys.contains(&name) {
            return Err(unknown(text, path, format, table, keys, key, &dotted));
        }
        match value.get_ref() {
            DeValue::Table(t) => walk(text, path, format, &dotted, t)?,
            DeValue::Array(items) => {
                for item in items.iter() {
                    if let DeValue::Table(t) = item.get_ref() {
                        walk(text, path, format, &dotted, t)?;
                    }
                }
            }
            _ => {}
        }
    }
    Ok(())
}

fn unknown(
    text: &str,
    path: &Path,
    format: u32,
    table: &'static str,
    keys: &'static [&'static str],
    key: &Spanned<std::borrow::Cow<'_, str>>,
    dotted: &str,
) -> ShotError {
    let (line, column) = line_column(text, key.span().start);
    let name = key.get_ref().as_ref();
    let shown = dotted.split('.').all(printable);
    ShotError::UnknownKey {
        path: path.into(),
        line,
        column,
        key: shown.then(|| dotted.to_string()),
        table,
        format,
        known: keys,
        suggestion: if shown { suggestion(name, keys) } else { None },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn known(path: &str) -> Option<&'static [&'static str]> {
        row(path).map(|(_, keys)| keys)
    }

    #[test]
    fn distance_and_suggestions() {
        assert_eq!(distance("placment", "placement"), 1);
        assert_eq!(distance("", "abc"), 3);
        assert_eq!(distance("yaw_degs", "yaw_deg"), 1);
        assert_eq!(distance("kitten", "sitting"), 3);
        assert_eq!(distance("modle", "model"), 1);
        assert_eq!(distance("abc", "abc"), 0);
        let top = known("").expect("top level");
        assert_eq!(suggestion("placment", top), Some("placement"));
        assert_eq!(suggestion("modle", top), Some("model"));
        assert_eq!(suggestion("colour", top), None);
        let placement = known("placement").expect("placement");
        assert_eq!(suggestion("yaw_degs", placement), Some("yaw_deg"));
        assert_eq!(suggestion("yaw", placement), Some("yaw_deg"));
    }

    #[test]
    fn every_table_row_is_reachable_from_the_top() {
        for (table, _) in KNOWN_KEYS {
            let mut parent = String::new();
            for part in table.split('.').filter(|p| !p.is_empty()) {
                let keys = known(&parent).unwrap_or_else(|| panic!("no row for {parent:?}"));
                assert!(keys.contains(&part), "{table}: {part} not in {parent:?}");
                parent = if parent.is_empty() {
                    part.to_string()
                } else {
                    format!("{parent}.{part}")
                };
            }
        }
        let names = field_names();
        for k in ["format", "scale", "key_poses", "marker", "tags", "size_m"] {
            assert!(names.contains(&k), "{k}");
        }
    }

    #[test]
    fn printable_names_only() {
        assert!(printable("yaw_degs"));
        assert!(printable("a-b_9"));
        assert!(!printable("root:x:0:0"));
        assert!(!printable("a b"));
        assert!(!printable(&"x".repeat(65)));
        assert!(!printable(""));
    }
}
