//! Every `VOLBENCH_*` environment variable volbench reads at run time, in
//! one table ([`SWITCHES`]), with the one parser of each value.
//!
//! - Each command checks the whole environment when it starts
//!   ([`check_environment`]): a bad value of any switch (`VOLBENCH_PEER_TIMEOUT_S=0`,
//!   `VOLBENCH_TEST_RENUMBER=hilbert`) or a `VOLBENCH_TEST_*` name that is
//!   not a switch (a misspelt knob would silently do nothing) is an error
//!   before any work, not after a suite has run.
//! - The code that uses a switch reads it through the typed getters here
//!   ([`flag`], [`int`], [`seconds`], [`choice`]), so the rules are the
//!   same at the start and at the use.
//! - The switches that change what is measured (every `VOLBENCH_TEST_*`
//!   knob, the validation layer, the device choice) are recorded in each
//!   result ([`recorded`]: `env_switches` in a run's JSON, the suite's
//!   summary and its report), so a slowed run says why.
//!
//! Nothing here knows about Vulkan; `vk` and `algo` use it, it uses neither.

use std::collections::BTreeMap;

/// What values a switch takes.
#[derive(Debug, Clone, Copy)]
pub enum Kind {
    /// 1/0, true/false, yes/no, on/off (any case, blanks ignored); empty is off.
    Flag,
    /// A whole number in `min..=max`.
    Int { min: u64, max: u64 },
    /// Seconds, fractions allowed, in `(0, max]`.
    Seconds { max: f64 },
    /// One of these words.
    Choice(&'static [&'static str]),
    /// A path or a name: any value (not checked here).
    Text,
}

/// One environment switch.
#[derive(Debug, Clone, Copy)]
pub struct Switch {
    pub name: &'static str,
    pub kind: Kind,
    /// Whether a set value changes what a run measures (recorded in results).
    pub recorded: bool,
    /// What it does, for `docs/usage.md` and messages.
    pub what: &'static str,
}

pub const VALIDATION: &str = "VOLBENCH_VALIDATION";
pub const DEVICE: &str = "VOLBENCH_DEVICE";
pub const FENCE_TIMEOUT_S: &str = "VOLBENCH_FENCE_TIMEOUT_S";
pub const PEER_TIMEOUT_S: &str = "VOLBENCH_PEER_TIMEOUT_S";
pub const DATA: &str = "VOLBENCH_DATA";
pub const CACHE: &str = "VOLBENCH_CACHE";
pub const VTK_VENV: &str = "VOLBENCH_VTK_VENV";
pub const COUNT_DIR: &str = "VOLBENCH_COUNT_DIR";
pub const COUNT_TIMEOUT_S: &str = "VOLBENCH_COUNT_TIMEOUT_S";
pub const COUNT_KEEP_DUMPS: &str = "VOLBENCH_COUNT_KEEP_DUMPS";
pub const TEST_DEVICE_LIMIT_BYTES: &str = "VOLBENCH_TEST_DEVICE_LIMIT_BYTES";
pub const TEST_PACK_AHEAD_BYTES: &str = "VOLBENCH_TEST_PACK_AHEAD_BYTES";
pub const TEST_EXTRA_FRAGMENT_WORK: &str = "VOLBENCH_TEST_EXTRA_FRAGMENT_WORK";
pub const TEST_RESIDENT_BATCH: &str = "VOLBENCH_TEST_RESIDENT_BATCH";
pub const TEST_BRICK_MAP_HOST: &str = "VOLBENCH_TEST_BRICK_MAP_HOST";
pub const TEST_RENUMBER: &str = "VOLBENCH_TEST_RENUMBER";
pub const TEST_STAGING_CHUNK_BYTES: &str = "VOLBENCH_TEST_STAGING_CHUNK_BYTES";

/// The prefix of the test-only knobs.
pub const TEST_PREFIX: &str = "VOLBENCH_TEST_";

const ANY: u64 = u64::MAX;

/// Every switch.
pub const SWITCHES: [Switch; 17] = [
    Switch { name: VALIDATION, kind: Kind::Flag, recorded: true, what: "turns the Vulkan validation layer on (slows every frame)" },
    Switch { name: DEVICE, kind: Kind::Text, recorded: true, what: "picks the Vulkan device by name or index" },
    Switch { name: FENCE_TIMEOUT_S, kind: Kind::Seconds { max: 86_400.0 }, recorded: false, what: "bounds every fence wait (default 60 s)" },
    Switch { name: PEER_TIMEOUT_S, kind: Kind::Int { min: 1, max: ANY }, recorded: false, what: "bounds each peer process, in whole seconds (default 900)" },
    Switch { name: DATA, kind: Kind::Text, recorded: false, what: "the folder of the shipped data" },
    Switch { name: CACHE, kind: Kind::Text, recorded: false, what: "the folder of the reference-image cache" },
    Switch { name: VTK_VENV, kind: Kind::Text, recorded: false, what: "the Python environment of the VTK peer" },
    Switch {
        name: COUNT_TIMEOUT_S,
        kind: Kind::Seconds { max: 604_800.0 },
        recorded: false,
        what: "bounds --count's run under valgrind (default 86400 s)",
    },
    Switch { name: COUNT_DIR, kind: Kind::Text, recorded: false, what: "set by volbench for its counted child (--count)" },
    Switch { name: COUNT_KEEP_DUMPS, kind: Kind::Text, recorded: false, what: "keeps --count's callgrind dumps in this folder" },
    Switch {
        name: TEST_DEVICE_LIMIT_BYTES,
        kind: Kind::Int { min: 16, max: ANY },
        recorded: true,
        what: "test only: lowers the device's buffer limits to this many bytes",
    },
    Switch { name: TEST_PACK_AHEAD_BYTES, kind: Kind::Int { min: 0, max: ANY }, recorded: true, what: "test only: balanced's pack-ahead bytes" },
    Switch {
        name: TEST_EXTRA_FRAGMENT_WORK,
        kind: Kind::Int { min: 0, max: 65_535 },
        recorded: true,
        what: "test only: a deliberate slowdown of balanced's fragment stage (multiply-adds)",
    },
    Switch { name: TEST_RESIDENT_BATCH, kind: Kind::Int { min: 1, max: ANY }, recorded: true, what: "test only: resident's cells per batch" },
    Switch { name: TEST_BRICK_MAP_HOST, kind: Kind::Flag, recorded: true, what: "test only: the ray casters' brick map through host memory" },
    Switch { name: TEST_RENUMBER, kind: Kind::Choice(&["morton"]), recorded: true, what: "test only: renumbers a loaded mesh for locality" },
    Switch {
        name: TEST_STAGING_CHUNK_BYTES,
        kind: Kind::Int { min: 1, max: ANY },
        recorded: true,
        what: "test only: the staging buffer's chunk bytes",
    },
];

/// A switch's value that is not one it takes.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{var}={value}: expected {expected}")]
pub struct BadValue {
    pub var: &'static str,
    pub value: String,
    pub expected: String,
}

fn switch(name: &str) -> Option<&'static Switch> {
    SWITCHES.iter().find(|s| s.name == name)
}

/// What values `kind` takes, in words.
fn expected(kind: Kind) -> String {
    match kind {
        Kind::Flag => "one of 1/0, true/false, yes/no, on/off (any case)".into(),
        Kind::Int { min, max: ANY } => format!("a whole number of at least {min}"),
        Kind::Int { min, max } => format!("a whole number in {min}..={max}"),
        Kind::Seconds { max } => format!("a number of seconds > 0 and <= {max}"),
        Kind::Choice(words) => format!("one of: {}", words.join(", ")),
        Kind::Text => "a UTF-8 value".into(),
    }
}

/// A parsed value.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Value {
    Flag(bool),
    Int(u64),
    Seconds(f64),
    Choice(&'static str),
    Text,
}

/// The one parser: `value` of switch `var` (of `kind`).
pub fn parse(var: &'static str, kind: Kind, value: &str) -> Result<Value, BadValue> {
    let bad = || BadValue { var, value: value.to_string(), expected: expected(kind) };
    let v = value.trim();
    match kind {
        Kind::Flag => match v.to_ascii_lowercase().as_str() {
            "1" | "true" | "yes" | "on" => Ok(Value::Flag(true)),
            "0" | "false" | "no" | "off" | "" => Ok(Value::Flag(false)),
            _ => Err(bad()),
        },
        Kind::Int { min, max } => v.parse::<u64>().ok().filter(|n| (min..=max).contains(n)).map(Value::Int).ok_or_else(bad),
        Kind::Seconds { max } => v.parse::<f64>().ok().filter(|s| *s > 0.0 && *s <= max).map(Value::Seconds).ok_or_else(bad),
        Kind::Choice(words) => words.iter().find(|w| **w == v).map(|w| Value::Choice(w)).ok_or_else(bad),
        Kind::Text => Ok(Value::Text),
    }
}

/// [`parse`] with `var`'s own kind from [`SWITCHES`].
pub fn parse_named(var: &'static str, value: &str) -> Result<Value, BadValue> {
    match switch(var) {
        Some(s) => parse(var, s.kind, value),
        None => Err(BadValue { var, value: value.to_string(), expected: "a switch listed in volbench::switches".into() }),
    }
}

/// Switch `var`'s value from the environment, parsed; `None` when unset.
/// A value that is not UTF-8 is an error, never "unset".
fn get(var: &'static str) -> Result<Option<Value>, BadValue> {
    let Some(s) = switch(var) else {
        // A caller's bug: every name read is in the table (a unit test checks).
        return Err(BadValue { var, value: String::new(), expected: "a switch listed in volbench::switches".into() });
    };
    match std::env::var(var) {
        Ok(v) => parse(var, s.kind, &v).map(Some),
        Err(std::env::VarError::NotPresent) => Ok(None),
        Err(std::env::VarError::NotUnicode(v)) => {
            Err(BadValue { var, value: v.to_string_lossy().into_owned(), expected: expected(s.kind) })
        }
    }
}

/// A [`Kind::Flag`] switch (unset: off).
pub fn flag(var: &'static str) -> Result<bool, BadValue> {
    Ok(matches!(get(var)?, Some(Value::Flag(true))))
}

/// A [`Kind::Int`] switch.
pub fn int(var: &'static str) -> Result<Option<u64>, BadValue> {
    Ok(match get(var)? {
        Some(Value::Int(n)) => Some(n),
        _ => None,
    })
}

/// A [`Kind::Seconds`] switch.
pub fn seconds(var: &'static str) -> Result<Option<f64>, BadValue> {
    Ok(match get(var)? {
        Some(Value::Seconds(s)) => Some(s),
        _ => None,
    })
}

/// A [`Kind::Choice`] switch.
pub fn choice(var: &'static str) -> Result<Option<&'static str>, BadValue> {
    Ok(match get(var)? {
        Some(Value::Choice(c)) => Some(c),
        _ => None,
    })
}

/// Checks every `VOLBENCH_*` variable of `vars`: each switch's value must
/// parse, and a `VOLBENCH_TEST_*` name must be a switch.
pub fn check_vars(vars: impl IntoIterator<Item = (String, String)>) -> Result<(), BadValue> {
    for (name, value) in vars {
        match SWITCHES.iter().find(|s| s.name == name) {
            Some(s) => {
                parse(s.name, s.kind, &value)?;
            }
            None if name.starts_with(TEST_PREFIX) => {
                return Err(BadValue {
                    var: "VOLBENCH_TEST_*",
                    value: format!("{name}={value}"),
                    expected: format!(
                        "one of the test switches: {}",
                        SWITCHES.iter().filter(|s| s.name.starts_with(TEST_PREFIX)).map(|s| s.name).collect::<Vec<_>>().join(", ")
                    ),
                })
            }
            None => {}
        }
    }
    Ok(())
}

/// [`check_vars`] over this process's environment (every command calls it
/// first). A switch whose value is not UTF-8 is an error, except the
/// [`Kind::Text`] ones (paths take any bytes).
pub fn check_environment() -> Result<(), BadValue> {
    let mut vars = Vec::new();
    for (k, v) in std::env::vars_os() {
        let key = k.to_string_lossy();
        if !key.starts_with("VOLBENCH_") {
            continue;
        }
        match (k.to_str(), v.to_str()) {
            (Some(k), Some(v)) => vars.push((k.to_string(), v.to_string())),
            (Some(_), None) if switch(&key).is_some_and(|s| matches!(s.kind, Kind::Text)) => {}
            _ => {
                let var = switch(&key).map_or("VOLBENCH_*", |s| s.name);
                return Err(BadValue { var, value: v.to_string_lossy().into_owned(), expected: "a UTF-8 name and value".into() });
            }
        }
    }
    check_vars(vars)
}

/// The switches of `vars` that change what a run measures, by name.
pub fn recorded_of(vars: impl IntoIterator<Item = (String, String)>) -> BTreeMap<String, String> {
    vars.into_iter().filter(|(k, _)| SWITCHES.iter().any(|s| s.recorded && s.name == k)).collect()
}

/// The set switches of this process that change what a run measures
/// (recorded as `env_switches` in results).
pub fn recorded() -> BTreeMap<String, String> {
    recorded_of(utf8_vars())
}

/// This process's environment variables whose name and value are UTF-8
/// (`std::env::vars` panics on the others; path variables may hold any
/// bytes, and the switches that must be UTF-8 are refused otherwise by
/// `check_environment`).
pub fn utf8_vars() -> impl Iterator<Item = (String, String)> {
    std::env::vars_os().filter_map(|(k, v)| Some((k.into_string().ok()?, v.into_string().ok()?)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn vars(v: &[(&str, &str)]) -> Vec<(String, String)> {
        v.iter().map(|(a, b)| (a.to_string(), b.to_string())).collect()
    }

    #[test]
    fn values_are_parsed_or_refused() {
        let k = |n: &str| switch(n).unwrap().kind;
        assert_eq!(parse(PEER_TIMEOUT_S, k(PEER_TIMEOUT_S), "5"), Ok(Value::Int(5)));
        for bad in ["0", "garbage", "-1", "1.5", ""] {
            let e = parse(PEER_TIMEOUT_S, k(PEER_TIMEOUT_S), bad).unwrap_err().to_string();
            assert_eq!(e, format!("VOLBENCH_PEER_TIMEOUT_S={bad}: expected a whole number of at least 1"));
        }
        // Bounds at two sizes.
        assert!(parse(TEST_EXTRA_FRAGMENT_WORK, k(TEST_EXTRA_FRAGMENT_WORK), "65535").is_ok());
        assert!(parse(TEST_EXTRA_FRAGMENT_WORK, k(TEST_EXTRA_FRAGMENT_WORK), "65536").is_err());
        assert!(parse(TEST_DEVICE_LIMIT_BYTES, k(TEST_DEVICE_LIMIT_BYTES), "16").is_ok());
        assert!(parse(TEST_DEVICE_LIMIT_BYTES, k(TEST_DEVICE_LIMIT_BYTES), "15").is_err());
        assert_eq!(parse(FENCE_TIMEOUT_S, k(FENCE_TIMEOUT_S), "0.5"), Ok(Value::Seconds(0.5)));
        assert!(parse(FENCE_TIMEOUT_S, k(FENCE_TIMEOUT_S), "86401").is_err());
        assert_eq!(parse(TEST_BRICK_MAP_HOST, Kind::Flag, " On "), Ok(Value::Flag(true)));
        assert!(parse(TEST_BRICK_MAP_HOST, Kind::Flag, "maybe").is_err());
        assert!(parse(TEST_RENUMBER, k(TEST_RENUMBER), "hilbert").unwrap_err().to_string().contains("one of: morton"));
    }

    #[test]
    fn the_environment_check_and_the_record() {
        assert!(check_vars(vars(&[("VOLBENCH_DATA", "x"), ("VOLBENCH_TEST_RENUMBER", "morton"), ("OTHER", "1")])).is_ok());
        let e = check_vars(vars(&[("VOLBENCH_TEST_RENUMBR", "morton")])).unwrap_err().to_string();
        assert!(e.contains("VOLBENCH_TEST_RENUMBR=morton") && e.contains("VOLBENCH_TEST_RENUMBER"), "{e}");
        assert!(check_vars(vars(&[("VOLBENCH_PEER_TIMEOUT_S", "0")])).is_err());
        let r = recorded_of(vars(&[("VOLBENCH_DATA", "x"), ("VOLBENCH_VALIDATION", "1"), ("VOLBENCH_TEST_RESIDENT_BATCH", "7")]));
        assert_eq!(r.into_iter().collect::<Vec<_>>(), vars(&[("VOLBENCH_TEST_RESIDENT_BATCH", "7"), ("VOLBENCH_VALIDATION", "1")]));
        // Every test knob is recorded; names are unique.
        assert!(SWITCHES.iter().filter(|s| s.name.starts_with(TEST_PREFIX)).all(|s| s.recorded));
        let mut names: Vec<_> = SWITCHES.iter().map(|s| s.name).collect();
        names.sort();
        names.dedup();
        assert_eq!(names.len(), SWITCHES.len());
    }
}
