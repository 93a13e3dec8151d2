//! Transfer functions as JSON files (`--tf FILE`; presets in `data/tf/`).
//!
//! # Format
//!
//! ```json
//! {
//!   "name": "bluntfin-default",
//!   "scalar_units": "relative",
//!   "attenuation_units": "per_diagonal",
//!   "points": [
//!     { "scalar": 0.0,  "color": [0.1, 0.2, 0.9], "attenuation": 4.0 },
//!     { "scalar": 0.3,  "color": [0.9, 0.9, 0.2], "opacity": 0.5, "unit_length": 0.05 },
//!     { "scalar": 1.0,  "color": [1.0, 0.1, 0.05], "attenuation": 40.0 }
//!   ]
//! }
//! ```
//!
//! Top level (unknown keys are errors, so typos do not pass silently):
//! - `name` (string, optional; default: the file stem).
//! - `scalar_units`: `"absolute"` (default: `scalar` is a value of the mesh's
//!   scalar field) or `"relative"` (`scalar` in [0, 1] over the mesh's scalar
//!   range `[lo, hi]`, mapped to `lo + scalar·(hi − lo)`).
//! - `attenuation_units`: `"per_world_unit"` (default) or `"per_diagonal"`:
//!   every length in the file (`attenuation`'s unit and `unit_length`) is
//!   measured in mesh diagonals instead of world units, so `attenuation` is the
//!   optical depth across one diagonal and the file reads the same whatever
//!   the mesh's units (the built-in presets are written this way).
//! - `unit_length` (optional): default `unit_length` for points given by
//!   `opacity`.
//! - `points`: at least one control point, scalars non-decreasing (two equal
//!   scalars make a step).
//!
//! Each point:
//! - `scalar`: finite number (see `scalar_units`).
//! - `color`: `[r, g, b]`, each in [0, 1]: the emitted colour, linear RGB.
//! - exactly one of
//!   - `attenuation`: τ ≥ 0, finite, per unit length (see `attenuation_units`);
//!   - `opacity` in [0, 1) with `unit_length` > 0 (on the point or at the top
//!     level): the opacity a homogeneous slab of that thickness has, so
//!     `τ = −ln(1 − opacity) / unit_length`.
//!
//! The result is the [`TransferFunction`] the renderers use: scalars absolute,
//! τ per world unit, piecewise linear between points, clamped outside them.
//!
//! Also rejected (a picture that would silently be blank or wrong):
//! - anything but a JSON object at the top level, and a key given twice in
//!   any object (JSON parsers differ on which one wins; serde_json keeps the
//!   last silently);
//! - τ per world unit, after the unit conversions, that is infinite or
//!   beyond f32's largest value (e.g. `opacity` over a `unit_length` of
//!   1e-320): the renderers hold τ in f32;
//! - a function whose every point has τ = 0: nothing would be drawn;
//! - `"per_diagonal"` on a mesh of zero extent (the mesh is reported).
//!
//! Relative scalars over a constant field (`lo == hi`) use the widened range
//! of [`effective_scalar_range`], so the field's value sits at relative 0.5
//! instead of on a step where all the points coincide.
//!
//! Every error names the file and, for a point, its index (from 0).
//!
//! [`to_json`] writes the same format (absolute units, or relative to a
//! mesh), with f64 values printed so that they read back bit for bit.

use std::path::{Path, PathBuf};

use anyhow::{anyhow, bail, Result};
use serde::{Deserialize, Serialize};

use super::{effective_scalar_range, ControlPoint, TransferFunction};

/// How scalars are given in a file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ScalarUnits {
    #[default]
    Absolute,
    Relative,
}

/// How lengths (attenuation's unit, `unit_length`) are given in a file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AttenuationUnits {
    #[default]
    PerWorldUnit,
    PerDiagonal,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct FileSpec {
    #[serde(default)]
    name: Option<String>,
    #[serde(default)]
    scalar_units: ScalarUnits,
    #[serde(default)]
    attenuation_units: AttenuationUnits,
    #[serde(default)]
    unit_length: Option<f64>,
    points: Vec<serde_json::Value>,
}

#[derive(Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
struct PointSpec {
    scalar: f64,
    color: [f64; 3],
    #[serde(default, skip_serializing_if = "Option::is_none")]
    attenuation: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    opacity: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    unit_length: Option<f64>,
}

/// A JSON value parsed by a visitor that refuses a key given twice in any
/// object (serde_json's own `Value` keeps the last one silently).
struct StrictValue(serde_json::Value);

impl<'de> Deserialize<'de> for StrictValue {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        d.deserialize_any(StrictVisitor)
    }
}

struct StrictVisitor;

impl<'de> serde::de::Visitor<'de> for StrictVisitor {
    type Value = StrictValue;

    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("a JSON value")
    }
    fn visit_bool<E>(self, v: bool) -> std::result::Result<StrictValue, E> {
        Ok(StrictValue(v.into()))
    }
    fn visit_i64<E>(self, v: i64) -> std::result::Result<StrictValue, E> {
        Ok(StrictValue(v.into()))
    }
    fn visit_u64<E>(self, v: u64) -> std::result::Result<StrictValue, E> {
        Ok(StrictValue(v.into()))
    }
    fn visit_f64<E>(self, v: f64) -> std::result::Result<StrictValue, E> {
        // JSON numbers are finite; `From<f64>` would turn a non-finite one into null.
        Ok(StrictValue(v.into()))
    }
    fn visit_str<E>(self, v: &str) -> std::result::Result<StrictValue, E> {
        Ok(StrictValue(v.into()))
    }
    fn visit_string<E>(self, v: String) -> std::result::Result<StrictValue, E> {
        Ok(StrictValue(v.into()))
    }
    fn visit_unit<E>(self) -> std::result::Result<StrictValue, E> {
        Ok(StrictValue(serde_json::Value::Null))
    }
    fn visit_seq<A: serde::de::SeqAccess<'de>>(self, mut seq: A) -> std::result::Result<StrictValue, A::Error> {
        let mut items = Vec::new();
        while let Some(StrictValue(v)) = seq.next_element()? {
            items.push(v);
        }
        Ok(StrictValue(serde_json::Value::Array(items)))
    }
    fn visit_map<A: serde::de::MapAccess<'de>>(self, mut map: A) -> std::result::Result<StrictValue, A::Error> {
        let mut out = serde_json::Map::new();
        while let Some(key) = map.next_key::<String>()? {
            if out.contains_key(&key) {
                return Err(serde::de::Error::custom(format!("duplicate key \"{key}\"")));
            }
            let StrictValue(v) = map.next_value()?;
            out.insert(key, v);
        }
        Ok(StrictValue(serde_json::Value::Object(out)))
    }
}

/// The JSON kind of `v`, for messages.
fn kind(v: &serde_json::Value) -> &'static str {
    match v {
        serde_json::Value::Null => "null",
        serde_json::Value::Bool(_) => "a boolean",
        serde_json::Value::Number(_) => "a number",
        serde_json::Value::String(_) => "a string",
        serde_json::Value::Array(_) => "an array",
        serde_json::Value::Object(_) => "an object",
    }
}

/// Reads a transfer function file (format: module docs). `scalar_range` is
/// the mesh's `(min, max)` scalar (used by `"scalar_units": "relative"`),
/// `mesh_diagonal` its bounding-box diagonal (used by
/// `"attenuation_units": "per_diagonal"`).
pub fn load_tf(path: impl AsRef<Path>, scalar_range: (f64, f64), mesh_diagonal: f64) -> Result<TransferFunction> {
    let path = path.as_ref();
    // A transfer function is a few control points: 1 MiB is generous.
    let text = crate::fsio::read_input_text(path, "transfer function", 1 << 20)?;
    let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "tf".into());
    parse_tf(&text, &path.display().to_string(), &stem, scalar_range, mesh_diagonal)
}

/// [`load_tf`] on text already read; `source` names it in errors,
/// `default_name` is used when the file has no `name`.
pub fn parse_tf(
    text: &str,
    source: &str,
    default_name: &str,
    scalar_range: (f64, f64),
    mesh_diagonal: f64,
) -> Result<TransferFunction> {
    let mut spec = read_spec(text, source)?;
    let (lo, hi) = scalar_range;
    if spec.scalar_units == ScalarUnits::Relative && !(lo.is_finite() && hi.is_finite() && lo <= hi) {
        bail!("{source}: relative scalars need a finite mesh scalar range, got [{lo}, {hi}]");
    }
    let (lo, hi) = effective_scalar_range(lo, hi);
    let unit = length_unit(&spec, source, mesh_diagonal)?;
    let values = std::mem::take(&mut spec.points);
    let mut points = Vec::with_capacity(values.len());
    let mut previous: Option<f64> = None;
    for (i, value) in values.into_iter().enumerate() {
        let at = || format!("{source}: point {i}");
        let p: PointSpec = serde_json::from_value(value).map_err(|e| anyhow!("{}: {e}", at()))?;
        check_point(&p, spec.scalar_units, previous, &at)?;
        previous = Some(p.scalar);
        let tau = point_attenuation(&p, &spec, unit, &at)?;
        let scalar = match spec.scalar_units {
            ScalarUnits::Absolute => p.scalar,
            // As `harness::datasets::default_transfer_function` does.
            ScalarUnits::Relative => lo + p.scalar * (hi - lo),
        };
        points.push(ControlPoint { scalar, color: p.color, attenuation: tau });
    }
    check_visible(&points, source, (lo, hi), mesh_diagonal)?;
    Ok(TransferFunction { name: spec.name.unwrap_or_else(|| default_name.to_string()), points })
}

/// The file's JSON as a [`FileSpec`]: an object (no duplicate keys, no
/// unknown fields) with at least one point.
fn read_spec(text: &str, source: &str) -> Result<FileSpec> {
    if text.trim().is_empty() {
        bail!("{source}: the file is empty; expected a JSON object with \"points\" (see data/tf/README.md)");
    }
    let StrictValue(value) =
        serde_json::from_str(text).map_err(|e| anyhow!("{source}: invalid transfer function JSON: {e}"))?;
    if !value.is_object() {
        bail!(
            "{source}: expected an object at the top level (a transfer function is a JSON object with \"points\"), \
             found {}",
            kind(&value)
        );
    }
    let spec: FileSpec =
        serde_json::from_value(value).map_err(|e| anyhow!("{source}: invalid transfer function JSON: {e}"))?;
    if spec.points.is_empty() {
        bail!("{source}: \"points\" is empty (at least one control point is required)");
    }
    Ok(spec)
}

/// The world length the file's lengths are in (1, or the mesh diagonal
/// for `per_diagonal`); the top-level `unit_length` checked too.
fn length_unit(spec: &FileSpec, source: &str, mesh_diagonal: f64) -> Result<f64> {
    let unit = match spec.attenuation_units {
        AttenuationUnits::PerWorldUnit => 1.0,
        AttenuationUnits::PerDiagonal => {
            if !(mesh_diagonal.is_finite() && mesh_diagonal > 0.0) {
                bail!(
                    "{source}: \"attenuation_units\": \"per_diagonal\" needs a mesh of positive extent, but the \
                     mesh's bounding-box diagonal is {mesh_diagonal}: the mesh is degenerate (all points at one \
                     place), not this file"
                );
            }
            mesh_diagonal
        }
    };
    if let Some(u) = spec.unit_length {
        if !(u.is_finite() && u > 0.0) {
            bail!("{source}: top-level \"unit_length\" must be finite and > 0, got {u}");
        }
    }
    Ok(unit)
}

/// Checks a point's scalar (finite, in [0, 1] when relative, not below
/// the `previous` point's) and colour (components in [0, 1]).
fn check_point(p: &PointSpec, units: ScalarUnits, previous: Option<f64>, at: &dyn Fn() -> String) -> Result<()> {
    if !p.scalar.is_finite() {
        bail!("{}: scalar {} is not finite", at(), p.scalar);
    }
    if units == ScalarUnits::Relative && !(0.0..=1.0).contains(&p.scalar) {
        bail!("{}: relative scalar {} is outside [0, 1]", at(), p.scalar);
    }
    if let Some(prev) = previous {
        if p.scalar < prev {
            bail!(
                "{}: scalar {} is below the previous point's {prev} (scalars must be non-decreasing)",
                at(),
                p.scalar
            );
        }
    }
    for (k, &c) in p.color.iter().enumerate() {
        if !(c.is_finite() && (0.0..=1.0).contains(&c)) {
            bail!("{}: color component {k} is {c}, outside [0, 1]", at());
        }
    }
    Ok(())
}

/// A point's attenuation per world unit, from its `attenuation` or its
/// `opacity` over `unit_length` (lengths in `unit` world units), checked
/// to fit in f32.
fn point_attenuation(p: &PointSpec, spec: &FileSpec, unit: f64, at: &dyn Fn() -> String) -> Result<f64> {
    let tau = match (p.attenuation, p.opacity) {
        (Some(_), Some(_)) => bail!("{}: give either \"attenuation\" or \"opacity\", not both", at()),
        (None, None) => bail!("{}: needs \"attenuation\" or \"opacity\" (with \"unit_length\")", at()),
        (Some(t), None) => {
            if p.unit_length.is_some() {
                bail!("{}: \"unit_length\" only goes with \"opacity\"", at());
            }
            if !(t.is_finite() && t >= 0.0) {
                bail!("{}: attenuation {t} must be finite and >= 0", at());
            }
            t / unit
        }
        (None, Some(o)) => {
            if !(o.is_finite() && (0.0..1.0).contains(&o)) {
                bail!("{}: opacity {o} is outside [0, 1)", at());
            }
            let len = p.unit_length.or(spec.unit_length).ok_or_else(|| {
                anyhow!("{}: \"opacity\" needs \"unit_length\" (on the point or at the top level)", at())
            })?;
            if !(len.is_finite() && len > 0.0) {
                bail!("{}: unit_length {len} must be finite and > 0", at());
            }
            -(-o).ln_1p() / (len * unit)
        }
    };
    if !(tau.is_finite() && tau <= f32::MAX as f64) {
        bail!(
            "{}: attenuation {tau:e} per world unit (after the unit conversions) is beyond the f32 range \
             (at most {:e}) the renderers hold it in; check \"attenuation\", \"opacity\" and \"unit_length\"{}",
            at(),
            f32::MAX,
            if spec.attenuation_units == AttenuationUnits::PerDiagonal {
                format!(" (lengths in mesh diagonals of {unit:e})")
            } else {
                String::new()
            }
        );
    }
    Ok(tau)
}

/// Refuses a function that would draw nothing over the data's scalars
/// `[lo, hi]`: every attenuation 0, or all too small to show.
fn check_visible(points: &[ControlPoint], source: &str, (lo, hi): (f64, f64), mesh_diagonal: f64) -> Result<()> {
    if points.iter().all(|p| p.attenuation == 0.0) {
        bail!(
            "{source}: every control point has attenuation 0, so nothing would be drawn (emission scales with \
             attenuation in the emission-absorption model)"
        );
    }
    // Not zero, but too small to show: across the whole mesh no point would
    // reach an opacity f32 resolves (the same rule the runner uses to tell
    // a wrong empty image from a right one).
    // Only the data's own scalars are ever looked up: a function opaque
    // only outside [lo, hi] draws a blank image just the same.
    let probe = TransferFunction { name: String::new(), points: points.to_vec() };
    if mesh_diagonal.is_finite() && mesh_diagonal > 0.0 && !probe.visible_over(lo, hi, mesh_diagonal) {
        let (first, last) = probe.scalar_range();
        bail!(
            "{source}: over the data's scalar range [{lo}, {hi}] the largest attenuation times the data's diagonal \
             ({mesh_diagonal:e}) is below 1e-4: nothing would be visible (control points span [{first}, {last}]; \
             attenuation that small underflows what f32 opacity resolves)"
        );
    }
    Ok(())
}

/// Units [`to_json`] writes in.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum JsonUnits {
    /// Scalars absolute, attenuation per world unit: lossless.
    Absolute,
    /// Scalars relative to `scalar_range`, attenuation per `mesh_diagonal`
    /// (the presets' form; reading back may differ in the last bits).
    RelativeTo { scalar_range: (f64, f64), mesh_diagonal: f64 },
}

/// Writes `tf` in the file format (pretty-printed JSON, attenuation form).
pub fn to_json(tf: &TransferFunction, units: JsonUnits) -> Result<String> {
    // scalar' = (scalar - lo) / span, tau' = tau · unit (exact for the
    // absolute form: lo = 0, span = unit = 1).
    let (scalar_units, attenuation_units, lo, span, unit) = match units {
        JsonUnits::Absolute => (ScalarUnits::Absolute, AttenuationUnits::PerWorldUnit, 0.0, 1.0, 1.0),
        JsonUnits::RelativeTo { scalar_range: (lo, hi), mesh_diagonal } => {
            if !(lo.is_finite() && hi.is_finite() && hi >= lo) {
                bail!("{}: cannot write relative scalars over the range [{lo}, {hi}]", tf.name);
            }
            if !(mesh_diagonal.is_finite() && mesh_diagonal > 0.0) {
                bail!("{}: cannot write attenuation per diagonal for a mesh diagonal of {mesh_diagonal}", tf.name);
            }
            // The same range `parse_tf` maps relative scalars over.
            let (lo, hi) = effective_scalar_range(lo, hi);
            (ScalarUnits::Relative, AttenuationUnits::PerDiagonal, lo, hi - lo, mesh_diagonal)
        }
    };
    #[derive(Serialize)]
    struct Out<'a> {
        name: &'a str,
        scalar_units: ScalarUnits,
        attenuation_units: AttenuationUnits,
        points: Vec<PointSpec>,
    }
    let out = Out {
        name: &tf.name,
        scalar_units,
        attenuation_units,
        points: tf
            .points
            .iter()
            .map(|p| {
                let scalar = (p.scalar - lo) / span;
                let attenuation = Some(p.attenuation * unit);
                PointSpec { scalar, color: p.color, attenuation, opacity: None, unit_length: None }
            })
            .collect(),
    };
    Ok(serde_json::to_string_pretty(&out)? + "\n")
}

/// The preset file of a shipped mesh (`data/tf/<name>.json`), if there is one.
pub fn preset_path(mesh_name: &str) -> Option<PathBuf> {
    let p = crate::data_dir::data_dir().join("tf").join(format!("{mesh_name}.json"));
    p.is_file().then_some(p)
}
