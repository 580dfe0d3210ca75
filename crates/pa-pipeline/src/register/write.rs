//! Writing a refined placement back into a shot file in place: only `[placement]`'s
//! `translation_m`, `yaw_deg` (and `scale` when refined) change; every comment, blank line and
//! other key stays as the user wrote it. The original is kept first as `SHOT.toml.bak` (or
//! `.bak.1`, `.bak.2`, ... when a backup exists: none is ever replaced), then the shot is
//! replaced atomically.

use std::path::{Path, PathBuf};

use toml_edit::{value, Array, DocumentMut, Item, Table, Value};

use super::PlacementParams;
use crate::shot::{Shot, ShotError, MAX_SHOT_BYTES};

/// Errors writing a placement into a shot file.
#[derive(Debug, thiserror::Error)]
pub enum WriteError {
    #[error(transparent)]
    Io(#[from] pa_io::IoError),
    /// The shot file is not TOML, or `placement` is not a table.
    #[error("{}: cannot update [placement]: {message}", path.display())]
    Edit { path: PathBuf, message: String },
    /// The edited text is no longer a valid shot (a bug: nothing is written).
    #[error(transparent)]
    Shot(#[from] ShotError),
    /// No free backup name (`.bak`, `.bak.1` ... `.bak.999` all exist).
    #[error("{}: no free backup name (.bak to .bak.999 exist): remove old backups", path.display())]
    NoBackupName { path: PathBuf },
}

/// Rounds to `digits` decimals (so that the file reads 0.0031, not 0.003100000023841858).
fn rounded(v: f64, digits: i32) -> f64 {
    let k = 10f64.powi(digits);
    (v * k).round() / k
}

/// Sets `key` in `table` to `new`, keeping the old value's comments and spacing.
fn set(table: &mut Table, key: &str, new: Value) {
    match table.get_mut(key).and_then(Item::as_value_mut) {
        Some(old) => {
            let decor = old.decor().clone();
            *old = new;
            *old.decor_mut() = decor;
        }
        None => {
            table.insert(key, value(new));
        }
    }
}

/// The shot's text with `[placement]` set to `placement` (`scale` written when `with_scale`).
pub fn placement_edited(
    text: &str,
    path: &Path,
    placement: &PlacementParams,
    with_scale: bool,
) -> Result<String, WriteError> {
    let edit = |message: String| WriteError::Edit {
        path: path.to_path_buf(),
        message,
    };
    let mut doc: DocumentMut = text
        .parse()
        .map_err(|e: toml_edit::TomlError| edit(e.message().to_string()))?;
    if !doc.contains_key("placement") {
        doc.insert("placement", Item::Table(Table::new()));
    }
    let table = doc["placement"]
        .as_table_mut()
        .ok_or_else(|| edit("`placement` is not a table".into()))?;
    let mut t = Array::new();
    for v in placement.translation_m {
        t.push(rounded(v, 7));
    }
    set(table, "translation_m", Value::Array(t));
    set(table, "yaw_deg", Value::from(rounded(placement.yaw_deg, 4)));
    if with_scale {
        set(table, "scale", Value::from(rounded(placement.scale, 6)));
    }
    let out = doc.to_string();
    // What is written must load as a shot.
    Shot::parse(&out, path)?;
    Ok(out)
}

/// `[placement] scale` of a shot's text, when it has a positive finite one.
pub fn placement_scale(text: &str) -> Option<f64> {
    let doc: DocumentMut = text.parse().ok()?;
    let v = doc.get("placement")?.get("scale")?;
    let s = v.as_float().or_else(|| v.as_integer().map(|i| i as f64))?;
    (s.is_finite() && s > 0.0).then_some(s)
}

/// The first free backup name of `shot`: `SHOT.bak`, then `SHOT.bak.1`, `SHOT.bak.2`, ...
fn backup_names(shot: &Path) -> impl Iterator<Item = PathBuf> + '_ {
    (0..1000).map(move |i| {
        let mut name = shot.as_os_str().to_owned();
        name.push(".bak");
        if i > 0 {
            name.push(format!(".{i}"));
        }
        PathBuf::from(name)
    })
}

/// Writes `placement` into the shot file at `path` in place, after a backup of the original;
/// returns the backup's path.
pub fn write_placement(
    path: &Path,
    placement: &PlacementParams,
    with_scale: bool,
) -> Result<PathBuf, WriteError> {
    let original = pa_io::read_regular(path, MAX_SHOT_BYTES, "a shot file")?;
    let text = String::from_utf8(original.clone()).map_err(|e| pa_io::IoError::NotText {
        path: path.to_path_buf(),
        offset: e.utf8_error().valid_up_to(),
    })?;
    let edited = placement_edited(&text, path, placement, with_scale)?;
    let mut backup = None;
    for name in backup_names(path) {
        if pa_io::write_new_atomic(&name, &original)? {
            backup = Some(name);
            break;
        }
    }
    let backup = backup.ok_or_else(|| WriteError::NoBackupName {
        path: path.to_path_buf(),
    })?;
    pa_io::write_atomic(path, edited.as_bytes())?;
    Ok(backup)
}
