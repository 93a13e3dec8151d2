//! Typed method settings, declared once per family.
//!
//! A family declares its settings with [`settings!`]: one line per option
//! (field, type, default, allowed values, build or run time, unit, help).
//! From that one declaration come the option table `volbench list` prints
//! and specs are parsed against (`OPTIONS`), and the typed struct the
//! family's methods read ([`MethodSettings::from_options`]); `build` marks
//! the options that change shader code, whose defines (and so pipeline
//! keys) the family derives in one place of its own (docs/architecture.md,
//! "One source of defines and pipeline keys per family"). Closed sets of words are enums declared with
//! [`choices!`]: the words exist once, in the enum, and the option table
//! reads them from there ([`choice`]).

use anyhow::{bail, Result};

use super::method::{OptionSpec, OptionValue, OptionValues, Options};

/// A closed set of words an option may take, declared with [`choices!`].
pub trait Choice: Sized + Copy + 'static {
    /// Every value, in the order of `NAMES`.
    const ALL: &'static [Self];
    /// The words, as specs write them.
    const NAMES: &'static [&'static str];
}

/// A settings field's type: how it is read from a parsed option value.
pub trait OptionType: Sized {
    fn from_value(v: &OptionValue) -> Option<Self>;
}

impl OptionType for f64 {
    fn from_value(v: &OptionValue) -> Option<Self> {
        match v {
            OptionValue::Float(x) => Some(*x),
            OptionValue::Int(x) => Some(*x as f64),
            _ => None,
        }
    }
}

impl OptionType for f32 {
    fn from_value(v: &OptionValue) -> Option<Self> {
        f64::from_value(v).map(|x| x as f32)
    }
}

impl OptionType for i64 {
    fn from_value(v: &OptionValue) -> Option<Self> {
        match v {
            OptionValue::Int(x) => Some(*x),
            _ => None,
        }
    }
}

impl OptionType for usize {
    fn from_value(v: &OptionValue) -> Option<Self> {
        i64::from_value(v).and_then(|x| usize::try_from(x).ok())
    }
}

impl OptionType for u32 {
    fn from_value(v: &OptionValue) -> Option<Self> {
        i64::from_value(v).and_then(|x| u32::try_from(x).ok())
    }
}

impl OptionType for bool {
    fn from_value(v: &OptionValue) -> Option<Self> {
        match v {
            OptionValue::Bool(x) => Some(*x),
            _ => None,
        }
    }
}

/// The value of a [`Choice`] named by `text`.
pub fn choice_from_text<T: Choice>(text: &str) -> Option<T> {
    T::NAMES.iter().position(|n| *n == text).map(|i| T::ALL[i])
}

/// The allowed values of a [`Choice`] option.
pub const fn choice<T: Choice>() -> OptionValues {
    OptionValues::Choice { values: T::NAMES }
}

/// A whole number in [min, max].
pub const fn int(min: i64, max: i64) -> OptionValues {
    OptionValues::Int { min, max }
}

/// A finite number in [min, max].
pub const fn float(min: f64, max: f64) -> OptionValues {
    OptionValues::Float { min, max }
}

/// on/off.
pub const fn flag() -> OptionValues {
    OptionValues::Bool
}

/// A family's typed settings (declared with [`settings!`]).
pub trait MethodSettings: Sized {
    /// Every option of the family, in the order `volbench list` prints them
    /// (a method may offer a subset: [`pick`]).
    const OPTIONS: &'static [OptionSpec];
    /// The typed values of a parsed option set; an option the method does
    /// not offer takes its default. Checks what no single option's range
    /// can (`check`).
    fn from_options(options: &Options) -> Result<Self>;
    /// Checks across options (e.g. a table size against the integrator's
    /// table limit); run on every spec when it is parsed.
    fn check(&self) -> Result<()> {
        Ok(())
    }
}

/// `MethodInfo::check` of a family: the option set makes valid settings.
pub fn check<S: MethodSettings>(options: &Options) -> Result<()> {
    S::from_options(options).map(|_| ())
}

/// One field of [`settings!`]'s `from_options`: the option's value, or its
/// default when the method does not offer it.
pub fn field<T: OptionType>(options: &Options, specs: &[OptionSpec], name: &str) -> Result<T> {
    let Some(spec) = specs.iter().find(|s| s.name == name) else { bail!("option '{name}' is not declared") };
    let value = match options.0.get(spec.name) {
        Some(v) => v.clone(),
        None => spec.parse("(default)", spec.default)?,
    };
    match T::from_value(&value) {
        Some(v) => Ok(v),
        None => bail!("option '{}': '{value}' is not a value of the setting's type", spec.name),
    }
}

/// The options of `all` named by `names`, in that order: a method's subset
/// of its family's table. A name `all` lacks stops the build.
pub const fn pick<const N: usize>(all: &[OptionSpec], names: [&str; N]) -> [OptionSpec; N] {
    assert!(!all.is_empty(), "pick from an empty option table");
    let mut out = [all[0]; N];
    let mut i = 0;
    while i < N {
        let mut j = 0;
        loop {
            assert!(j < all.len(), "pick: an option name the family does not declare");
            if str_eq(all[j].name, names[i]) {
                out[i] = all[j];
                break;
            }
            j += 1;
        }
        i += 1;
    }
    out
}

const fn str_eq(a: &str, b: &str) -> bool {
    let (a, b) = (a.as_bytes(), b.as_bytes());
    if a.len() != b.len() {
        return false;
    }
    let mut i = 0;
    while i < a.len() {
        if a[i] != b[i] {
            return false;
        }
        i += 1;
    }
    true
}

/// Declares an enum whose variants are an option's words, each once:
///
/// ```ignore
/// choices! {
///     /// How a cell's segment is integrated.
///     #[derive(Default)]
///     pub enum Integrator { Average = "average", #[default] Ppi = "ppi" }
/// }
/// ```
///
/// gives the enum (Debug, Clone, Copy, PartialEq, Eq, Hash), `name()`,
/// serde serialisation as the word, [`Choice`] and [`OptionType`].
#[macro_export]
macro_rules! choices {
    (
        $(#[$meta:meta])*
        $vis:vis enum $name:ident { $( $(#[$vmeta:meta])* $variant:ident = $text:literal ),+ $(,)? }
    ) => {
        $(#[$meta])*
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
        $vis enum $name { $( $(#[$vmeta])* $variant ),+ }

        impl $name {
            /// The word a spec writes for this value.
            pub fn name(self) -> &'static str {
                match self { $( $name::$variant => $text ),+ }
            }
        }

        impl $crate::algo::settings::Choice for $name {
            const ALL: &'static [Self] = &[$( $name::$variant ),+];
            const NAMES: &'static [&'static str] = &[$( $text ),+];
        }

        impl $crate::algo::settings::OptionType for $name {
            fn from_value(v: &$crate::algo::method::OptionValue) -> Option<Self> {
                match v {
                    $crate::algo::method::OptionValue::Text(t) => $crate::algo::settings::choice_from_text(t),
                    _ => None,
                }
            }
        }

        impl serde::Serialize for $name {
            fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
                s.serialize_str(self.name())
            }
        }
    };
}

/// Declares a family's settings: a struct with one typed field per option
/// and its [`MethodSettings`] table, from one line per option:
///
/// ```ignore
/// settings! {
///     pub struct Settings {
///         step: f64 = "0.5", float(0.05, 8.0), run, "voxels", "largest distance between samples";
///         shade: bool = "off", flag(), build, "", "Blinn-Phong lighting";
///     }
/// }
/// ```
///
/// `build` marks an option that changes shader code, `run` a run-time
/// parameter. An optional `impl { ... }` block after the fields holds the
/// family's `check` (placed in the `MethodSettings` impl).
#[macro_export]
macro_rules! settings {
    (@when build) => { true };
    (@when run) => { false };
    (
        $(#[$meta:meta])*
        $vis:vis struct $name:ident {
            $( $(#[$fmeta:meta])* $field:ident : $ty:ty = $default:literal, $values:expr, $when:ident, $unit:literal, $help:expr; )+
        }
        $(impl { $($body:tt)* })?
    ) => {
        $(#[$meta])*
        #[derive(Debug, Clone, Copy, PartialEq)]
        $vis struct $name { $( $(#[$fmeta])* pub $field: $ty, )+ }

        impl $crate::algo::settings::MethodSettings for $name {
            const OPTIONS: &'static [$crate::algo::method::OptionSpec] = &[$(
                $crate::algo::method::OptionSpec {
                    name: stringify!($field),
                    default: $default,
                    unit: $unit,
                    values: $values,
                    build_time: $crate::settings!(@when $when),
                    help: $help,
                },
            )+];

            fn from_options(options: &$crate::algo::method::Options) -> anyhow::Result<Self> {
                let specs = <Self as $crate::algo::settings::MethodSettings>::OPTIONS;
                let settings = $name { $(
                    $field: $crate::algo::settings::field(options, specs, stringify!($field))?,
                )+ };
                $crate::algo::settings::MethodSettings::check(&settings)?;
                Ok(settings)
            }

            $($($body)*)?
        }
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    crate::choices! {
        #[derive(Default)]
        enum Colour { #[default] Red = "red", DarkBlue = "dark-blue" }
    }

    crate::settings! {
        struct Demo {
            colour: Colour = "red", choice::<Colour>(), build, "", "a colour";
            size: usize = "4", int(1, 64), run, "px", "a size";
            gain: f64 = "0.5", float(0.0, 1.0), run, "", "a gain";
            on: bool = "on", flag(), run, "", "a switch";
        }
        impl {
            fn check(&self) -> anyhow::Result<()> {
                anyhow::ensure!(self.size != 3, "size 3 is unlucky");
                Ok(())
            }
        }
    }

    fn parse(pairs: &[(&str, &str)]) -> Result<Options> {
        let mut out = std::collections::BTreeMap::new();
        for o in Demo::OPTIONS {
            let text = pairs.iter().find(|(k, _)| *k == o.name).map_or(o.default, |(_, v)| *v);
            out.insert(o.name.to_string(), o.parse("demo", text)?);
        }
        Ok(Options(out))
    }

    #[test]
    fn one_declaration_gives_the_table_and_the_typed_values() {
        let names: Vec<_> = Demo::OPTIONS.iter().map(|o| o.name).collect();
        assert_eq!(names, ["colour", "size", "gain", "on"]);
        assert_eq!(Demo::OPTIONS[0].values, OptionValues::Choice { values: &["red", "dark-blue"] });
        assert!(Demo::OPTIONS[0].build_time && !Demo::OPTIONS[1].build_time);
        let d = Demo::from_options(&parse(&[]).unwrap()).unwrap();
        assert_eq!(d, Demo { colour: Colour::Red, size: 4, gain: 0.5, on: true });
        let d = Demo::from_options(&parse(&[("colour", "dark-blue"), ("size", "9"), ("on", "off")]).unwrap()).unwrap();
        assert_eq!((d.colour, d.size, d.on), (Colour::DarkBlue, 9, false));
        assert_eq!(d.colour.name(), "dark-blue");
        assert_eq!(serde_json::to_string(&d.colour).unwrap(), "\"dark-blue\"");
        // An option a method does not offer takes its default.
        let mut partial = parse(&[("size", "7")]).unwrap();
        partial.0.remove("gain");
        assert_eq!(Demo::from_options(&partial).unwrap().gain, 0.5);
        // Checks across options run on every parse.
        let e = Demo::from_options(&parse(&[("size", "3")]).unwrap()).unwrap_err().to_string();
        assert!(e.contains("unlucky"), "{e}");
        let e = parse(&[("colour", "green")]).unwrap_err().to_string();
        assert!(e.contains("'colour'") && e.contains("red, dark-blue") && e.contains("'green'"), "{e}");
    }

    #[test]
    fn pick_takes_a_subset_in_the_given_order() {
        const SUB: [OptionSpec; 2] = pick(Demo::OPTIONS, ["gain", "colour"]);
        assert_eq!(SUB.map(|o| o.name), ["gain", "colour"]);
    }
}
