//! What the suite runs: its settings (standard or `--quick`), the scenes a
//! run may be seen in, its datasets (the shipped ones, or those `--data`
//! names: shipped names and users' files), and the plan — the registry
//! crossed with those datasets, filtered, with each method's published and
//! suite option sets and the culling scenes.

use anyhow::{Context as _, Result};
use serde::Serialize;

use crate::algo::method::DataKind;
use crate::algo::registry::{MethodSpec, Registry};
use crate::harness::datasets::{self, Dataset};
use crate::harness::run::RunConfig;

/// How the suite runs: standard settings, or `--quick` ones.
#[derive(Debug, Clone, Serialize)]
pub struct SuiteSettings {
    pub width: u32,
    pub height: u32,
    pub frames: usize,
    pub warmup: usize,
    pub orbit_step_deg: f64,
    pub quick: bool,
    /// Only runs whose method or dataset name is listed (empty: all).
    pub filter: Vec<String>,
    /// Peers (`--peers`, see `harness::peers`) run on the same datasets,
    /// alternating with volbench's runs.
    pub peers: Vec<String>,
    /// With peers: after each dataset, this many rounds of each peer
    /// renderer against the two fastest runs at no more error
    /// (`suite::rounds`); 0 without peers.
    pub rounds: usize,
    /// Counted (`--count`): each run counts its timed frames' instructions
    /// (`harness::count`); no CPU reference, no diagnostics.
    pub counted: bool,
    /// The counted child's dump directory.
    #[serde(skip)]
    pub count_dir: Option<std::path::PathBuf>,
    /// How a mesh file's cell array is shown (`--cell-data`; each run's
    /// `dataset.stats` records it).
    #[serde(skip)]
    pub cell_data: crate::mesh::cell_data::CellData,
    /// `--data`: the datasets to run, in order (shipped names, or files,
    /// `FILE#SCALAR` as for `run`); empty: every shipped dataset.
    pub data: Vec<String>,
    /// `--tf FILE`: the transfer function of every dataset's standard scene
    /// instead of its preset (or, for a user's file, the generic ramp).
    pub tf: Option<std::path::PathBuf>,
}

impl SuiteSettings {
    pub fn standard(quick: bool, filter: Vec<String>) -> Self {
        let (width, height, frames, warmup) = if quick { (256, 256, 3, 1) } else { (512, 512, 20, 3) };
        SuiteSettings {
            width,
            height,
            frames,
            warmup,
            orbit_step_deg: 5.0,
            quick,
            filter,
            peers: Vec::new(),
            rounds: 0,
            counted: false,
            count_dir: None,
            data: Vec::new(),
            tf: None,
            cell_data: Default::default(),
        }
    }

    /// The rounds against the peers when `--rounds` is not given.
    pub fn default_rounds(quick: bool) -> usize {
        if quick {
            1
        } else {
            3
        }
    }

    /// The counted suite (`--count`): the quick one at 64x64 and 2 timed
    /// frames (a count repeats without many samples; CI's budget).
    pub fn counted(mut self, count_dir: Option<std::path::PathBuf>) -> Self {
        if count_dir.is_some() {
            if self.quick {
                (self.width, self.height, self.frames, self.warmup) = (64, 64, 2, 1);
            }
            self.counted = true;
            self.count_dir = count_dir;
        }
        self
    }

    pub(super) fn run_config(&self) -> RunConfig {
        RunConfig {
            width: self.width,
            height: self.height,
            frames: self.frames,
            warmup: self.warmup,
            orbit_step: self.orbit_step_deg.to_radians(),
            diagnostics: self.count_dir.is_none(),
            overlap: self.count_dir.is_none(),
            count_dir: self.count_dir.clone(),
            ..RunConfig::default()
        }
    }
}

/// A dataset of the suite: a shipped one, or a user's file (`--data FILE`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SuiteDataset {
    /// How rows, pictures and file names call it: a shipped dataset's name;
    /// for a file its stem (and `-SCALAR` when one is named), made of
    /// letters, digits, `.`, `_` and `-` only, and suffixed `-2`, `-3`, ...
    /// where it would repeat another dataset's name.
    pub name: String,
    /// What `datasets::load` is given: the shipped name, or the file as
    /// `--data` gave it (`FILE` or `FILE#SCALAR`).
    pub source: String,
    pub kind: DataKind,
    /// A user's file: its peers read the original file with their own
    /// readers (`harness::peers::original_dataset`), not volbench's export.
    pub user: bool,
}

impl SuiteDataset {
    fn shipped(d: &datasets::NamedDataset) -> Self {
        SuiteDataset { name: d.name.to_string(), source: d.name.to_string(), kind: d.kind, user: false }
    }

    /// Read it (the one place the suite loads a dataset: the plan's check of
    /// a user's file and each dataset's runs), named as the suite names it.
    pub(super) fn load(&self, cell_data: crate::mesh::cell_data::CellData) -> Result<Dataset> {
        let mut d = datasets::load_with(&self.source, cell_data)?;
        d.name = self.name.clone();
        Ok(d)
    }
}

/// The name a user's file goes by in the suite (see [`SuiteDataset::name`]),
/// unique among `taken`.
fn user_dataset_name(source: &str, taken: &[String]) -> String {
    let (file, scalar) = match source.rsplit_once('#') {
        Some((f, s)) if std::fs::symlink_metadata(source).is_err() => (f, Some(s)),
        _ => (source, None),
    };
    let path = std::path::Path::new(file);
    let mut stem = path.file_name().map(|f| f.to_string_lossy().into_owned()).unwrap_or_default();
    // `mesh.vtu` -> `mesh`, `head.nii.gz` -> `head`.
    if let Some(s) = stem.strip_suffix(".gz") {
        stem = s.to_string();
    }
    if let Some(i) = stem.rfind('.').filter(|&i| i > 0) {
        stem.truncate(i);
    }
    let clean = |s: &str| -> String { s.chars().map(|c| if c.is_ascii_alphanumeric() || "._-".contains(c) { c } else { '_' }).collect() };
    let mut base = clean(&stem);
    if let Some(s) = scalar {
        base = format!("{base}-{}", clean(s));
    }
    if base.is_empty() || base.starts_with('.') {
        base = format!("data{base}");
    }
    let mut name = base.clone();
    let mut k = 2;
    while taken.contains(&name) || datasets::NAMED.iter().any(|d| d.name == name) {
        name = format!("{base}-{k}");
        k += 1;
    }
    name
}

/// The suite's datasets without loading anything: every shipped one when
/// `--data` is not given, else those it lists in its order (kinds of users'
/// files are filled in by [`plan`], which reads them). A dataset listed
/// twice is an error.
fn named_datasets(settings: &SuiteSettings) -> Result<Vec<SuiteDataset>> {
    if settings.data.is_empty() {
        return Ok(datasets::NAMED.iter().map(SuiteDataset::shipped).collect());
    }
    let mut out: Vec<SuiteDataset> = Vec::new();
    for (i, source) in settings.data.iter().enumerate() {
        anyhow::ensure!(!settings.data[..i].contains(source), "--data {source}: given twice");
        anyhow::ensure!(!source.is_empty(), "--data: an empty name; give a shipped dataset (`volbench list`) or a file");
        match datasets::NAMED.iter().find(|d| d.name == source) {
            Some(d) => out.push(SuiteDataset::shipped(d)),
            None => {
                let taken: Vec<String> = out.iter().map(|d| d.name.clone()).collect();
                // The kind is known once the file is read (in `plan`).
                out.push(SuiteDataset { name: user_dataset_name(source, &taken), source: source.clone(), kind: DataKind::TetMesh, user: true });
            }
        }
    }
    Ok(out)
}

/// One planned run: a dataset and a method at its defaults, or with an
/// option set a published figure names; or a culling scene.
#[derive(Debug)]
pub struct PlannedRun {
    pub dataset: SuiteDataset,
    pub spec: MethodSpec,
    pub scene: Scene,
}

impl PlannedRun {
    /// How the run is named in rows and reports: the spec's label, and the
    /// scene when it is not the standard one (`balanced:cull=off @zoomed`).
    pub fn label(&self) -> String {
        match self.scene {
            Scene::Standard => self.spec.label(),
            s => format!("{} @{}", self.spec.label(), s.name()),
        }
    }

    /// The montage a run's image goes to: its dataset, and the scene when
    /// it is not the standard one (another view, another reference).
    pub(super) fn montage_group(&self) -> String {
        match self.scene {
            Scene::Standard => self.dataset.name.clone(),
            s => format!("{}@{}", self.dataset.name, s.name()),
        }
    }

    pub(super) fn file_stem(&self) -> String {
        match self.scene {
            Scene::Standard => self.spec.file_stem(),
            s => format!("{}@{}", self.spec.file_stem(), s.name()),
        }
    }
}

/// The view and transfer function of a run: the standard orbit with the
/// dataset's preset, or one of the scenes where culling matters
/// (`algo::cell_projection::cull`), each run with culling on and off.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Scene {
    Standard,
    /// The dataset's `<name>-band` transfer function (`data/tf/`): opaque
    /// only in a narrow band of the scalar range, most cells transparent.
    Transparent,
    /// The orbit zoomed in [`ZOOM`] times (`RunConfig::zoom`: aimed off
    /// the centre): most cells off-screen.
    Zoomed,
    /// The orbit's first view for every frame.
    Still,
}

/// The zoomed scene's factor.
pub const ZOOM: f64 = 4.0;

/// The datasets the culling scenes run on (the oxygen post: its preset and
/// its `oxygenpost-band` transfer function).
pub const CULL_SCENE_DATASETS: &[&str] = &["oxygenpost"];

impl Scene {
    pub const CULLING: [Scene; 3] = [Scene::Transparent, Scene::Zoomed, Scene::Still];

    pub fn name(self) -> &'static str {
        match self {
            Scene::Standard => "standard",
            Scene::Transparent => "transparent",
            Scene::Zoomed => "zoomed",
            Scene::Still => "still",
        }
    }

    /// The run configuration of this scene from the suite's.
    pub(super) fn config(self, cfg: &RunConfig) -> RunConfig {
        match self {
            Scene::Standard | Scene::Transparent => cfg.clone(),
            // Its magnified cells make a frame several times a standard
            // one: a third of the timed frames keeps the suite's budget.
            Scene::Zoomed => RunConfig { zoom: ZOOM, frames: (cfg.frames / 3).max(1), ..cfg.clone() },
            Scene::Still => RunConfig { orbit_step: 0.0, ..cfg.clone() },
        }
    }

    /// The transfer function of this scene on `dataset`: `tf` (`--tf`) or
    /// the dataset's own; the transparent scene's band function whatever
    /// `tf` says.
    pub(super) fn transfer_function(self, dataset: &Dataset, tf: Option<&std::path::Path>) -> Result<crate::scene::TransferFunction> {
        match (self, tf) {
            (Scene::Transparent, _) => {
                let path = crate::data_dir::data_dir().join("tf").join(format!("{}-band.json", dataset.name));
                dataset.load_transfer_function(&path)
            }
            (_, Some(path)) => dataset.load_transfer_function(path).with_context(|| format!("--tf {}", path.display())),
            (_, None) => dataset.default_transfer_function(),
        }
    }
}

/// Every (dataset, method for its kind) pair that passes the filter — the
/// datasets are the shipped ones, or those `--data` lists —: the defaults,
/// then each option set a published figure about the method on that
/// dataset names (so every published ratio has its measured counterpart in
/// the same run), then the method's own suite sets (`MethodInfo::suite`:
/// the cheap end of its accuracy trade-off). Before anything runs: a
/// `--filter` naming nothing of the suite, a peer not installed, a user's
/// file that does not load and a `--tf` file that cannot be used are errors.
pub fn plan(registry: &Registry, settings: &SuiteSettings) -> Result<Vec<PlannedRun>> {
    let keep = |name: &str| settings.filter.is_empty() || settings.filter.iter().any(|f| f == name);
    let mut suite_datasets = named_datasets(settings)?;
    for f in &settings.filter {
        if registry.names().contains(&f.as_str()) || suite_datasets.iter().any(|d| d.name == *f) {
            continue;
        }
        if settings.data.is_empty() {
            anyhow::bail!("--filter {f}: neither a registered method nor a shipped dataset (see `volbench list`)");
        }
        let names: Vec<&str> = suite_datasets.iter().map(|d| d.name.as_str()).collect();
        anyhow::bail!("--filter {f}: neither a registered method nor one of this suite's datasets ({})", names.join(", "));
    }
    // A peer that is not installed is an error before anything runs.
    for p in &settings.peers {
        crate::harness::peers::locate(p)?;
    }
    // A user's file is read once here, so that a bad one stops the suite
    // before it starts; the runs read it again (one dataset in memory at a time).
    for d in suite_datasets.iter_mut().filter(|d| d.user) {
        let loaded = d.load(settings.cell_data).with_context(|| format!("--data {}", d.source))?;
        d.kind = loaded.kind();
        // The peers read the original: a format they have no reader for
        // (or a PLOT3D pair's missing half) is known now.
        if !settings.peers.is_empty() && d.kind != DataKind::Terrain {
            crate::harness::peers::original_dataset(&loaded, &d.name, &d.source).with_context(|| format!("--data {} for --peers", d.source))?;
        }
        if let Some(path) = &settings.tf {
            loaded.load_transfer_function(path).with_context(|| format!("--tf {} on --data {}", path.display(), d.source))?;
        }
    }
    if let Some(path) = &settings.tf {
        // Shipped datasets are read when they run: the file itself is checked now.
        crate::scene::tf_file::load_tf(path, (0.0, 1.0), 1.0).with_context(|| format!("--tf {}", path.display()))?;
    }
    let mut out = Vec::new();
    for d in &suite_datasets {
        for m in registry.for_kind(d.kind) {
            if keep(&d.name) || keep(m.name) {
                let mut specs = vec![registry.parse_spec(m.name, &[])?];
                let published = m.published.iter().filter(|p| p.applies_to(&d.name)).map(|p| registry.published_spec(p));
                let own = m.suite.iter().map(|o| registry.parse_spec(&format!("{}:{o}", m.name), &[]));
                for s in published.chain(own) {
                    let s = s?;
                    if !specs.iter().any(|x| x.canonical() == s.canonical()) {
                        specs.push(s);
                    }
                }
                out.extend(specs.into_iter().map(|spec| PlannedRun { dataset: d.clone(), spec, scene: Scene::Standard }));
            }
        }
        // The culling scenes: the first methods with their family's culling
        // option (`Family::culling_option`: the papers' VICP and balanced;
        // --quick: the first only), culling on and off (the unchanged-image
        // check and the speed-up). Every method culls alike (tests/cull.rs);
        // more would not fit the suite's budget.
        if !d.user && CULL_SCENE_DATASETS.contains(&d.name.as_str()) {
            let culling: Vec<_> = registry
                .for_kind(d.kind)
                .filter(|m| (keep(&d.name) || keep(m.name)) && m.culling_option().is_some())
                .take(if settings.quick { 1 } else { 2 })
                .collect();
            // --quick leaves out the zoomed scene: magnified cells cost many
            // more fragments (the CI budget).
            for scene in Scene::CULLING.into_iter().filter(|&s| !(settings.quick && s == Scene::Zoomed)) {
                for m in &culling {
                    let option = m.culling_option().unwrap_or_default();
                    for cull in ["on", "off"] {
                        let spec = registry.parse_spec(&format!("{}:{option}={cull}", m.name), &[])?;
                        out.push(PlannedRun { dataset: d.clone(), spec, scene });
                    }
                }
            }
        }
    }
    anyhow::ensure!(!out.is_empty(), "--filter {:?} leaves nothing to run", settings.filter);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn users_files_get_unique_file_safe_names() {
        let mut taken = Vec::new();
        for (source, want) in [
            ("/x/mesh.vtu", "mesh"),
            ("/y/mesh.vtu", "mesh-2"),
            ("/x/mesh.vtu#pressure", "mesh-pressure"),
            ("/x/head.nii.gz", "head"),
            ("/x/hydrogen.vti", "hydrogen-2"),
            ("/x/a b|c.vtk#p/q", "a_b_c-p_q"),
            ("/x/.vtu", "data.vtu"),
        ] {
            let name = user_dataset_name(source, &taken);
            assert_eq!(name, want, "{source}");
            taken.push(name);
        }
    }

    #[test]
    fn data_lists_shipped_names_and_files_once_each() {
        let with = |data: &[&str]| SuiteSettings { data: data.iter().map(|s| s.to_string()).collect(), ..SuiteSettings::standard(true, vec![]) };
        let all = named_datasets(&with(&[])).unwrap();
        assert_eq!(all.len(), datasets::NAMED.len());
        assert!(all.iter().all(|d| !d.user));
        let two = named_datasets(&with(&["post-small", "/x/m.vtu"])).unwrap();
        assert_eq!((two[0].user, two[0].name.as_str()), (false, "post-small"));
        assert_eq!((two[1].user, two[1].name.as_str(), two[1].source.as_str()), (true, "m", "/x/m.vtu"));
        let e = named_datasets(&with(&["/x/m.vtu", "/x/m.vtu"])).unwrap_err().to_string();
        assert!(e.contains("/x/m.vtu") && e.contains("twice"), "{e}");
    }
}
