//! Every method volbench knows, one line each. The harness iterates over a
//! [`Registry`] and never names a method; tests build registries with extra
//! methods of their own (`Registry::with`).

use anyhow::{bail, Result};

use super::method::{parse_pairs, DataKind, MethodInfo, Options, Published};

#[derive(Clone, Debug)]
pub struct Registry {
    methods: Vec<MethodInfo>,
}

/// The methods shipped with volbench.
pub fn builtin() -> Registry {
    Registry {
        methods: vec![
            super::cell_projection::vicp::METHOD,
            super::cell_projection::balanced::METHOD,
            super::cell_projection::resident::METHOD,
            super::cell_projection::resident_gpusort::METHOD,
            super::cell_projection::atfs::METHOD,
            super::cell_projection::pt_compute::METHOD,
            super::tet_raycast::METHOD,
            super::raycast::fragment::METHOD,
            super::raycast::compute::METHOD,
            super::terrain::cpu::METHOD,
            super::terrain::gpu::METHOD,
            super::terrain::compute::METHOD,
        ],
    }
}

/// A method with its complete option set, as parsed from a spec
/// (`name:key=value,...`, vkmark style).
#[derive(Debug, Clone)]
pub struct MethodSpec {
    pub info: MethodInfo,
    pub options: Options,
}

impl MethodSpec {
    /// An error unless the method renders `kind` (`what` names the data).
    pub fn check_renders(&self, kind: DataKind, what: &str) -> Result<()> {
        anyhow::ensure!(
            self.info.data == kind,
            "method '{}' renders {} datasets; '{what}' is a {}",
            self.info.name,
            self.info.data.name(),
            kind.name()
        );
        Ok(())
    }

    /// The method and the options that differ from its defaults
    /// (`balanced`, `balanced:interpolation=paper`): how tables name a run.
    pub fn label(&self) -> String {
        let changed: Vec<String> = self
            .info
            .options
            .iter()
            .filter_map(|o| {
                let v = self.options.0.get(o.name)?;
                let default = o.parse(self.info.name, o.default).ok()?;
                (v != &default).then(|| format!("{}={v}", o.name))
            })
            .collect();
        if changed.is_empty() {
            self.info.name.to_string()
        } else {
            format!("{}:{}", self.info.name, changed.join(","))
        }
    }

    /// `label` as a file-name part.
    pub fn file_stem(&self) -> String {
        self.label()
            .chars()
            .map(|c| match c {
                ':' | '=' => '-',
                ',' => '_',
                c if c.is_ascii_alphanumeric() || c == '-' || c == '_' || c == '.' => c,
                _ => '_',
            })
            .collect()
    }

    /// `name:options` with every option written out (what results record).
    pub fn canonical(&self) -> String {
        let o = self.options.to_spec_string();
        if o.is_empty() {
            self.info.name.to_string()
        } else {
            format!("{}:{o}", self.info.name)
        }
    }
}

impl Registry {
    /// Add a method (tests; a name already present is replaced).
    pub fn with(mut self, info: MethodInfo) -> Self {
        self.methods.retain(|m| m.name != info.name);
        self.methods.push(info);
        self
    }

    pub fn methods(&self) -> &[MethodInfo] {
        &self.methods
    }

    /// The methods that render `kind`.
    pub fn for_kind(&self, kind: DataKind) -> impl Iterator<Item = &MethodInfo> {
        self.methods.iter().filter(move |m| m.data == kind)
    }

    pub fn get(&self, name: &str) -> Result<&MethodInfo> {
        match self.methods.iter().find(|m| m.name == name) {
            Some(m) => Ok(m),
            None => bail!("unknown method '{name}' (known: {})", self.names().join(", ")),
        }
    }

    /// Every method's published figures.
    pub fn published(&self) -> Vec<Published> {
        self.methods.iter().flat_map(|m| m.published.iter().copied()).collect()
    }

    /// The spec a published figure was measured with.
    pub fn published_spec(&self, p: &Published) -> Result<MethodSpec> {
        let text = if p.options.is_empty() { p.method.to_string() } else { format!("{}:{}", p.method, p.options) };
        self.parse_spec(&text, &[]).map_err(|e| anyhow::anyhow!("published figure ({}): {e:#}", p.source))
    }

    /// The published figures about a run of `spec` (canonical) on
    /// `dataset`: the same method with the same option set.
    pub fn published_for(&self, spec: &str, dataset: &str) -> Vec<Published> {
        self.published()
            .into_iter()
            .filter(|p| p.applies_to(dataset) && self.published_spec(p).is_ok_and(|s| s.canonical() == spec))
            .collect()
    }

    pub fn names(&self) -> Vec<&'static str> {
        self.methods.iter().map(|m| m.name).collect()
    }

    /// Parse `name[:key=value,...]`; `extra` option pairs (shorthand flags)
    /// apply after the spec's own defaults but before its explicit pairs,
    /// and must be options the method has.
    pub fn parse_spec(&self, spec: &str, extra: &[(&str, String)]) -> Result<MethodSpec> {
        let (name, rest) = spec.split_once(':').unwrap_or((spec, ""));
        let info = self.get(name.trim())?.clone();
        let pairs = parse_pairs(rest).map_err(|e| anyhow::anyhow!("method spec '{spec}': {e}"))?;
        let given = extra.iter().map(|(k, v)| (*k, v.as_str())).chain(pairs);
        let options = info.options_from(given)?;
        Ok(MethodSpec { info, options })
    }

    /// A method's option set `variant` (`key=value,...`) on top of `base`.
    pub fn variant(&self, base: &MethodSpec, variant: &str) -> Result<MethodSpec> {
        let pairs = parse_pairs(variant)?;
        let given: Vec<(String, String)> =
            base.options.0.iter().map(|(k, v)| (k.clone(), v.to_string())).collect();
        let options = base
            .info
            .options_from(given.iter().map(|(k, v)| (k.as_str(), v.as_str())).chain(pairs))?;
        Ok(MethodSpec { info: base.info.clone(), options })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn specs_parse_and_reject_what_a_method_lacks() {
        let r = builtin();
        let s = r.parse_spec("balanced:integrator=preint,sort=mpvo", &[]).unwrap();
        assert_eq!(s.options.text("integrator").unwrap(), "preint");
        assert_eq!(s.options.text("interpolation").unwrap(), "exact", "defaults filled in");
        assert!(s.canonical().starts_with("balanced:cull=on,distance_clamp=1000,integrator=preint"));
        let e = r.parse_spec("balanced:integrater=ppi", &[]).unwrap_err().to_string();
        assert!(e.contains("'balanced'") && e.contains("'integrater'"), "{e}");
        let e = r.parse_spec("balanced:table_size=99999", &[]).unwrap_err().to_string();
        assert!(e.contains("table_size") && e.contains("out of range"), "{e}");
        let e = r.parse_spec("vicp:sort=random", &[]).unwrap_err().to_string();
        assert!(e.contains("sort") && e.contains("centroid, mpvo"), "{e}");
        let e = r.parse_spec("nosuch", &[]).unwrap_err().to_string();
        assert!(e.contains("unknown method 'nosuch'") && e.contains("balanced"), "{e}");
        let e = r.parse_spec("vicp:ppi", &[]).unwrap_err().to_string();
        assert!(e.contains("not key=value"), "{e}");
        let e = r.parse_spec("balanced:integrator=ppi,integrator=preint", &[]).unwrap_err().to_string();
        assert!(e.contains("'integrator' is given twice"), "{e}");
        // Shorthand flags apply, and the spec's own pairs win over them.
        let s = r.parse_spec("vicp:sort=mpvo", &[("sort", "centroid".into()), ("integrator", "average".into())]).unwrap();
        assert_eq!(s.options.text("sort").unwrap(), "mpvo");
        assert_eq!(s.options.text("integrator").unwrap(), "average");
    }

    #[test]
    fn every_builtin_variant_is_valid() {
        let r = builtin();
        for m in r.methods() {
            let base = r.parse_spec(m.name, &[]).unwrap();
            for v in m.sweep.iter().chain(m.compare).chain(m.stress) {
                r.variant(&base, v).unwrap_or_else(|e| panic!("{}: '{v}': {e}", m.name));
            }
        }
    }
}
