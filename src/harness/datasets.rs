//! Datasets of every kind behind one name space: `--data NAME|PATH`. A
//! [`Dataset`] is the loaded data plus what results and the reference cache
//! need to know about it: its name, kind, where it came from and a digest of
//! its content (SHA-256 of what the images depend on, so a cache entry is
//! never served for different data under the same name).

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::{Context as _, Result};
use serde::Serialize;
use sha2::{Digest as _, Sha256};

use crate::algo::method::{DataKind, SceneData};
use crate::mesh::cell_data::CellData;
use crate::mesh::{self, Bounds, TetMesh};
use crate::terrain::Heightmap;
use crate::volume::Volume;
use crate::scene::{Camera, ControlPoint, TransferFunction};

/// A shipped dataset: its name, kind and what it is.
pub struct NamedDataset {
    pub name: &'static str,
    pub kind: DataKind,
    pub description: &'static str,
}

/// Every dataset shipped in `data/` (see data/README.md for provenance).
pub const NAMED: &[NamedDataset] = &[
    NamedDataset {
        name: "bluntfin",
        kind: DataKind::TetMesh,
        description: "NASA blunt fin, 40x32x32 PLOT3D grid split into 187,395 tets; density",
    },
    NamedDataset {
        name: "oxygenpost",
        kind: DataKind::TetMesh,
        description: "NASA liquid-oxygen post, 38x76x38 PLOT3D grid split into 513,375 tets; velocity magnitude",
    },
    NamedDataset {
        name: "post-small",
        kind: DataKind::TetMesh,
        description: "VTK's tetrahedral post (8,750 tets); pressure",
    },
    NamedDataset {
        name: "chest-ct",
        kind: DataKind::Volume,
        description: "LIDC chest CT, 256x256x133 uint8, spacing 1.40625x1.40625x2.5 mm",
    },
    NamedDataset { name: "headsq", kind: DataKind::Volume, description: "VTK's headsq MRI, 64x64x93 int16" },
    NamedDataset { name: "hydrogen", kind: DataKind::Volume, description: "hydrogen atom probability density (VTK XML ImageData)" },
    NamedDataset {
        name: "jacksboro",
        kind: DataKind::Terrain,
        description: "USGS 3-arc-second elevation model of the Jacksboro fault, 403x344 int16 metres (NumPy .npz)",
    },
];

/// The named meshes (kept for callers that only take meshes).
pub const NAMED_MESHES: [&str; 3] = ["bluntfin", "oxygenpost", "post-small"];

pub use crate::data_dir::data_dir;

/// The loaded data, by kind.
pub enum DatasetData {
    /// The mesh only: each method derives the per-cell data it needs (f32
    /// cells, centroids) from it, so no f64 per-cell precomputation
    /// (`TetGeometry`, 192 bytes per tet) is held for the run.
    TetMesh { mesh: TetMesh },
    Volume(Volume),
    Terrain(Heightmap),
}

/// A loaded dataset (see the module note).
pub struct Dataset {
    /// The name it was asked for (named) or the file stem.
    pub name: String,
    /// Shipped under this name (its preset transfer function applies).
    pub named: bool,
    /// Where it came from (path given, or the shipped file).
    pub source: String,
    /// SHA-256 of the content the images depend on, hex.
    pub digest: String,
    pub data: DatasetData,
    /// A volume's samples set aside for the next method set up
    /// ([`Dataset::hand_over_samples`]).
    handed: std::sync::Mutex<Option<crate::volume::Samples>>,
    /// What [`load`] was given for a volume: where its samples are read
    /// again after a method took them ([`Dataset::run_handing_over`]).
    loaded_from: Option<String>,
}

/// What every result records about its dataset.
#[derive(Debug, Clone, Serialize)]
pub struct DatasetSummary {
    pub name: String,
    pub kind: DataKind,
    pub source: String,
    pub digest: String,
    /// Sizes by unit (`cells`, `points`, `voxels`, ...).
    pub counts: BTreeMap<&'static str, u64>,
    /// Kind-specific facts (a mesh's load statistics, ...).
    pub stats: serde_json::Value,
}

impl Dataset {
    pub fn from_mesh(mut mesh: TetMesh, named: bool, source: String) -> Self {
        // Readers grow their vectors as they go: give back the spare
        // capacity (up to half of each) for the run.
        mesh.points.shrink_to_fit();
        mesh.scalars.shrink_to_fit();
        mesh.tets.shrink_to_fit();
        let digest = mesh_digest(&mesh);
        Dataset { name: mesh.name.clone(), named, source, digest, data: DatasetData::TetMesh { mesh }, handed: Default::default(), loaded_from: None }
    }

    /// A mesh read from a file or a shipped dataset: as `from_mesh`; with
    /// `VOLBENCH_TEST_RENUMBER=morton` its cells and points are first
    /// renumbered for locality (`mesh::reorder`). Off by default: measured
    /// no faster, and at 4.1 M tets possibly slower (docs/scaling.md,
    /// "Renumbering for locality"). The digest (the reference cache's key) is of the data
    /// as read; the renumbered mesh is the same mesh, so its reference is
    /// the same.
    pub fn from_loaded_mesh(mesh: TetMesh, named: bool, source: String) -> Self {
        let mut dataset = Self::from_mesh(mesh, named, source);
        // A bad value was refused when the command started (`switches::check_environment`).
        let renumber = crate::switches::choice(RENUMBER_VAR).ok().flatten() == Some("morton");
        if let (DatasetData::TetMesh { mesh }, true) = (&mut dataset.data, renumber) {
            mesh::reorder::spatial_order(mesh);
        }
        dataset
    }

    pub fn from_volume(volume: Volume, named: bool, source: String) -> Self {
        let digest = volume_digest(&volume);
        Dataset { name: volume.name.clone(), named, source, digest, data: DatasetData::Volume(volume), handed: Default::default(), loaded_from: None }
    }

    pub fn from_heightmap(map: Heightmap, named: bool, source: String) -> Self {
        let digest = heightmap_digest(&map);
        Dataset { name: map.name.clone(), named, source, digest, data: DatasetData::Terrain(map), handed: Default::default(), loaded_from: None }
    }

    /// For a caller that reads a volume's samples no more after the next
    /// method's set-up (a single run, its reference computed first): they
    /// are taken from the volume (`Volume::take_samples`; it keeps its grid:
    /// bounds, range, sizes) and given to that method
    /// (`MethodInputs::samples`), which gives them back as they reach the
    /// device. Nothing for other data.
    pub fn hand_over_samples(&mut self) {
        if let DatasetData::Volume(v) = &mut self.data {
            *self.handed.get_mut().unwrap_or_else(|p| p.into_inner()) = Some(v.take_samples());
        }
    }

    /// One method's run (`run`) on this dataset in a command that runs
    /// several: a volume loaded from a file ([`load`]) hands its samples over
    /// to the method, which frees them as they reach the device, and reads
    /// them again from the file after the run (loading is not in frame
    /// time; the content is checked against the digest). So a suite holds
    /// one copy of the volume at a time, as `volbench run` does
    /// (docs/bad-input.md, "Memory"). Other data, and a volume made in
    /// memory, are shared as they are. The run's own error is `run`'s
    /// result; reading the volume again is this one's.
    pub fn run_handing_over<T>(&mut self, run: impl FnOnce(&Dataset) -> T) -> Result<T> {
        let Some(from) = self.loaded_from.clone().filter(|_| matches!(self.data, DatasetData::Volume(_))) else {
            return Ok(run(self));
        };
        self.hand_over_samples();
        let out = run(self);
        // Set aside but not taken (the run failed before its set-up).
        let unused = self.take_handed_samples();
        let DatasetData::Volume(v) = &mut self.data else { unreachable!("checked above") };
        match unused {
            Some(samples) => v.give_samples_back(samples),
            None => {
                let again = load(&from).with_context(|| format!("reading '{from}' again for the next method"))?;
                anyhow::ensure!(
                    again.digest == self.digest,
                    "'{from}' changed while it was being run (its content's digest is not the one it was loaded with)"
                );
                self.data = again.data;
            }
        }
        Ok(out)
    }

    /// The samples [`Dataset::hand_over_samples`] set aside, once.
    pub(crate) fn take_handed_samples(&self) -> Option<crate::volume::Samples> {
        self.handed.lock().unwrap_or_else(|p| p.into_inner()).take()
    }

    pub fn kind(&self) -> DataKind {
        self.scene().kind()
    }

    /// What a method is built from.
    pub fn scene(&self) -> SceneData<'_> {
        match &self.data {
            DatasetData::TetMesh { mesh } => SceneData::TetMesh { mesh },
            DatasetData::Volume(v) => SceneData::Volume(v),
            DatasetData::Terrain(t) => SceneData::Terrain(t),
        }
    }

    pub fn bounds(&self) -> Bounds {
        match &self.data {
            DatasetData::TetMesh { mesh, .. } => mesh.bounds(),
            DatasetData::Volume(v) => v.bounds(),
            DatasetData::Terrain(t) => {
                let [ex, ey] = t.extent();
                let (lo, hi) = t.range();
                Bounds { min: [0.0, 0.0, lo], max: [ex, ey, hi] }
            }
        }
    }

    pub fn scalar_range(&self) -> (f64, f64) {
        match &self.data {
            DatasetData::TetMesh { mesh, .. } => mesh.scalar_range(),
            DatasetData::Volume(v) => v.range(),
            DatasetData::Terrain(t) => t.range(),
        }
    }

    /// The transfer function it is shown with unless `--tf` says otherwise;
    /// an error when the dataset's preset file cannot be used.
    pub fn default_transfer_function(&self) -> Result<TransferFunction> {
        Ok(match &self.data {
            DatasetData::TetMesh { mesh, .. } => mesh_transfer_function(mesh, self.named.then_some(self.name.as_str())),
            DatasetData::Volume(v) => volume_transfer_function(v, self.named.then_some(self.name.as_str()))?,
            DatasetData::Terrain(t) => terrain_colour_ramp(t),
        })
    }

    /// `--tf FILE` read against this dataset's scalar range and size.
    pub fn load_transfer_function(&self, path: &Path) -> Result<TransferFunction> {
        crate::scene::tf_file::load_tf(path, self.scalar_range(), self.bounds().diagonal())
    }

    /// The camera orbiting the dataset at `angle` radians.
    pub fn orbit_camera(&self, angle: f64, projection: crate::scene::Projection) -> Camera {
        Camera::orbit(&self.bounds(), angle, projection)
    }

    pub fn summary(&self) -> DatasetSummary {
        match &self.data {
            DatasetData::TetMesh { mesh, .. } => DatasetSummary {
                name: self.name.clone(),
                kind: self.kind(),
                source: self.source.clone(),
                digest: self.digest.clone(),
                counts: BTreeMap::from([("cells", mesh.tets.len() as u64), ("points", mesh.points.len() as u64)]),
                stats: serde_json::to_value(&mesh.stats).unwrap_or_default(),
            },
            DatasetData::Volume(v) => DatasetSummary {
                name: self.name.clone(),
                kind: self.kind(),
                source: self.source.clone(),
                digest: self.digest.clone(),
                counts: BTreeMap::from([("voxels", v.len() as u64)]),
                stats: serde_json::json!({
                    "dims": v.dims(),
                    "spacing": v.spacing(),
                    "origin": v.origin(),
                    "sample_type": v.sample_type().name(),
                    "range": [v.range().0, v.range().1],
                }),
            },
            DatasetData::Terrain(t) => DatasetSummary {
                name: self.name.clone(),
                kind: self.kind(),
                source: self.source.clone(),
                digest: self.digest.clone(),
                counts: BTreeMap::from([("samples", t.heights.len() as u64)]),
                stats: serde_json::json!({
                    "grid": [t.nx, t.ny],
                    "spacing": t.spacing,
                    "range": [t.range().0, t.range().1],
                    "nodata_filled": t.nodata_filled,
                }),
            },
        }
    }

    /// The f64 CPU reference image of this dataset, by kind.
    pub fn reference_image(&self, tf: &TransferFunction, camera: &Camera, width: u32, height: u32) -> Result<Vec<[f32; 4]>> {
        match &self.data {
            DatasetData::TetMesh { mesh, .. } => {
                let r = crate::reference::render_reference(mesh, camera, tf, width, height)
                    .with_context(|| format!("rendering the f64 reference of '{}'", self.name))?;
                Ok(r.pixels.iter().map(|p| p.map(|c| c as f32)).collect())
            }
            DatasetData::Volume(v) => {
                let r = crate::reference::render_volume_reference(v, camera, tf, width, height)
                    .with_context(|| format!("rendering the f64 reference of '{}'", self.name))?;
                Ok(r.pixels.iter().map(|p| p.map(|c| c as f32)).collect())
            }
            DatasetData::Terrain(_) => anyhow::bail!(
                "'{}' is a terrain: there is no f64 image reference for terrains; their error is geometric \
                 (height against the full-resolution grid, in the result's details)",
                self.name
            ),
        }
    }

    /// What the reference is, for `error.reference`.
    pub fn reference_description(&self) -> &'static str {
        match &self.data {
            DatasetData::TetMesh { .. } => "f64 CPU ray walk over face adjacency, exact emission-absorption",
            DatasetData::Volume(_) => "f64 CPU ray march of the trilinear field",
            DatasetData::Terrain(_) => "none (terrain error is geometric)",
        }
    }
}

/// SHA-256 over a mesh's points, scalars and cells (little-endian bytes).
pub fn mesh_digest(mesh: &TetMesh) -> String {
    let mut h = Sha256::new();
    h.update(b"volbench tet mesh v1\0");
    h.update((mesh.points.len() as u64).to_le_bytes());
    for p in &mesh.points {
        for c in p {
            h.update(c.to_le_bytes());
        }
    }
    for s in &mesh.scalars {
        h.update(s.to_le_bytes());
    }
    h.update((mesh.tets.len() as u64).to_le_bytes());
    for t in &mesh.tets {
        for i in t {
            h.update(i.to_le_bytes());
        }
    }
    // Constant cells: which faces join (the walks' adjacency) follows the
    // copied points; nothing is added for other meshes (their digests stay).
    if !mesh.stats.vertex_origin.is_empty() {
        h.update(b"vertex origin\0");
        for v in &mesh.stats.vertex_origin {
            h.update(v.to_le_bytes());
        }
    }
    hex(&h.finalize())
}

pub fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// SHA-256 over a volume's grid (dims, spacing, origin) and samples as f64.
pub fn volume_digest(v: &Volume) -> String {
    let mut h = Sha256::new();
    h.update(b"volbench volume v1\0");
    for d in v.dims() {
        h.update((d as u64).to_le_bytes());
    }
    for x in v.spacing().into_iter().chain(v.origin()) {
        h.update(x.to_le_bytes());
    }
    h.update(v.sample_type().name().as_bytes());
    for i in 0..v.len() {
        h.update(v.samples().get(i).unwrap_or(f64::NAN).to_le_bytes());
    }
    hex(&h.finalize())
}

/// SHA-256 over a height grid's size, spacing and heights.
pub fn heightmap_digest(t: &Heightmap) -> String {
    let mut h = Sha256::new();
    h.update(b"volbench heightmap v1\0");
    h.update((t.nx as u64).to_le_bytes());
    h.update((t.ny as u64).to_le_bytes());
    for s in t.spacing {
        h.update(s.to_le_bytes());
    }
    for z in &t.heights {
        h.update(z.to_le_bytes());
    }
    hex(&h.finalize())
}

/// A terrain's colours by height (low green, brown, high white): what the
/// shaded terrain images are tinted with.
pub fn terrain_colour_ramp(t: &Heightmap) -> TransferFunction {
    let (lo, hi) = crate::scene::effective_scalar_range(t.range().0, t.range().1);
    let stops = [(0.0, [0.25, 0.5, 0.2]), (0.5, [0.55, 0.45, 0.3]), (1.0, [0.95, 0.95, 0.95])];
    TransferFunction {
        name: "terrain-hypsometric".into(),
        points: stops.iter().map(|&(f, color)| ControlPoint { scalar: lo + f * (hi - lo), color, attenuation: 1.0 }).collect(),
    }
}

/// The first 64 KiB of an input (a VTK title line may be 256 bytes and
/// more; the DATASET line follows it).
fn head_of(p: &Path) -> Vec<u8> {
    use std::io::Read as _;
    let mut buf = Vec::new();
    if crate::fsio::check_input(p, "dataset", crate::fsio::MAX_INPUT_BYTES).is_ok() {
        if let Ok(f) = std::fs::File::open(p) {
            let _ = f.take(1 << 16).read_to_end(&mut buf);
        }
    }
    buf
}

/// What kind of data a file holds, by its content: the magic bytes of each
/// format (and for VTK, the DATASET line or XML type), whatever its name.
fn kind_by_content(head: &[u8]) -> Option<DataKind> {
    use crate::volume::Format;
    let text = String::from_utf8_lossy(head).to_ascii_uppercase();
    match crate::volume::sniff(head) {
        Some(Format::Nrrd | Format::Nifti | Format::MetaImage) => return Some(DataKind::Volume),
        Some(Format::VtkLegacy) => {
            return Some(if text.contains("STRUCTURED_POINTS") { DataKind::Volume } else { DataKind::TetMesh });
        }
        Some(Format::Vti) if text.contains("IMAGEDATA") => return Some(DataKind::Volume),
        Some(Format::Vti) if text.contains("UNSTRUCTUREDGRID") => return Some(DataKind::TetMesh),
        Some(Format::Vti) => return None,
        None => {}
    }
    crate::terrain::sniff(head).map(|_| DataKind::Terrain)
}

/// What kind of data a file's extension says it holds.
fn kind_by_extension(p: &Path) -> Option<DataKind> {
    let ext = p.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
    if crate::terrain::format_of_extension(p).is_some() {
        Some(DataKind::Terrain)
    } else if ext != "vtk" && crate::volume::format_of_extension(p).is_some() {
        Some(DataKind::Volume)
    } else if mesh::datasets::VTK_EXTENSIONS.contains(&ext.as_str()) || mesh::datasets::PLOT3D_EXTENSIONS.contains(&ext.as_str()) {
        Some(DataKind::TetMesh)
    } else {
        None
    }
}

/// Every format a path may hold, by kind (for the error when none fits).
pub fn supported_formats() -> String {
    format!(
        "meshes: {}; volumes: {}; terrain: .npy, .npz (NumPy), .tif/.tiff (GeoTIFF)",
        mesh::datasets::SUPPORTED_FORMATS,
        crate::volume::SUPPORTED_FORMATS
    )
}

/// Measurement knob: `morton` renumbers a loaded mesh for locality
/// (`Dataset::from_loaded_mesh`).
pub const RENUMBER_VAR: &str = crate::switches::TEST_RENUMBER;

/// Load a dataset by shipped name or path.
pub fn load(spec: &str) -> Result<Dataset> {
    load_with(spec, CellData::default())
}

/// [`load`], a mesh file's cell array shown as `cell_data` says
/// (`--cell-data`; `mesh::cell_data`). When a cell array is used because
/// the file has no point scalar, a note says so on stderr.
pub fn load_with(spec: &str, cell_data: CellData) -> Result<Dataset> {
    let mut dataset = load_once(spec, cell_data)?;
    if let DatasetData::Volume(_) = dataset.data {
        dataset.loaded_from = Some(spec.to_string());
    }
    if let DatasetData::TetMesh { mesh } = &dataset.data {
        if let Some(note) = mesh.stats.scalar.as_ref().and_then(|s| s.fallback_note(spec)) {
            crate::progress!("volbench: {note}");
        }
    }
    Ok(dataset)
}

/// [`load`]'s reading.
fn load_once(spec: &str, cell_data: CellData) -> Result<Dataset> {
    use mesh::cell_data::ScalarChoice;
    let dir = data_dir();
    let named = |name: &str, mesh: Result<TetMesh>, source: String| -> Result<Dataset> {
        let mut mesh = mesh.with_context(|| format!("loading dataset '{name}' ({})", crate::data_dir::search_note()))?;
        // Results name a shipped dataset the way the command line does.
        mesh.name = name.to_string();
        Ok(Dataset::from_loaded_mesh(mesh, true, source))
    };
    match spec {
        "bluntfin" => named(spec, mesh::datasets::load_bluntfin(&dir), "data/plot3d/bluntfin{xyz,q}.bin".into()),
        "oxygenpost" => named(spec, mesh::datasets::load_oxygenpost(&dir), "data/plot3d/post{xyz,q}.bin".into()),
        "post-small" => named(spec, mesh::datasets::load_post_small(&dir), "data/unstructured/post_tets_vtkdata.vtk".into()),
        name if crate::terrain::datasets::NAMES.contains(&name) => {
            let t = crate::terrain::datasets::load_named(name, &dir)
                .with_context(|| format!("loading dataset '{name}' ({})", crate::data_dir::search_note()))?;
            let file = crate::terrain::datasets::file_of(name).unwrap_or_default();
            Ok(Dataset::from_heightmap(t, true, format!("data/{file}")))
        }
        name if crate::volume::datasets::NAMES.contains(&name) => {
            let mut v = crate::volume::datasets::load_named(name, &dir)
                .with_context(|| format!("loading dataset '{name}' ({})", crate::data_dir::search_note()))?;
            v.name = name.to_string();
            let file = crate::volume::datasets::file_of(name).unwrap_or_default();
            Ok(Dataset::from_volume(v, true, format!("data/{file}")))
        }
        path => {
            // `file.npz#name` picks an array of an archive; `mesh.vtu#name` a point array.
            if let Some((file, array)) = path.rsplit_once('#') {
                let p = Path::new(file);
                let ext = p.extension().map(|e| e.to_string_lossy().to_ascii_lowercase());
                if ext.is_some_and(|e| mesh::datasets::VTK_EXTENSIONS.contains(&e.as_str()))
                    && std::fs::symlink_metadata(path).is_err()
                    && kind_by_content(&head_of(p)) != Some(DataKind::Volume)
                {
                    let choice = ScalarChoice { array: Some(array), cell_data };
                    let mesh = mesh::datasets::load_path_with(p, choice).with_context(|| format!("loading dataset '{path}'"))?;
                    return Ok(Dataset::from_loaded_mesh(mesh, false, path.to_string()));
                }
                if crate::terrain::format_of_extension(p).is_some() && std::fs::symlink_metadata(path).is_err() {
                    let t = crate::terrain::load_heightmap(p, Some(array)).with_context(|| format!("loading dataset '{path}'"))?;
                    return Ok(Dataset::from_heightmap(t, false, path.to_string()));
                }
            }
            let p = Path::new(path);
            if std::fs::symlink_metadata(p).is_err() {
                anyhow::bail!(
                    "dataset '{path}': no such file, and not one of the shipped datasets ({})",
                    NAMED.iter().map(|d| d.name).collect::<Vec<_>>().join(", ")
                );
            }
            // The content decides where it is recognised; the extension
            // only where it is not (a PLOT3D file has no magic).
            let head = head_of(p);
            let by_content = kind_by_content(&head);
            match by_content.or_else(|| kind_by_extension(p)) {
                Some(DataKind::Terrain) => {
                    let t = crate::terrain::load_heightmap(p, None).with_context(|| format!("loading dataset '{path}'"))?;
                    Ok(Dataset::from_heightmap(t, false, path.to_string()))
                }
                Some(DataKind::Volume) => {
                    let v = crate::volume::load_volume(p).with_context(|| format!("loading dataset '{path}'"))?;
                    Ok(Dataset::from_volume(v, false, path.to_string()))
                }
                Some(DataKind::TetMesh) => {
                    // A known mesh extension picks its reader; otherwise the content does.
                    let choice = ScalarChoice { array: None, cell_data };
                    let mesh = if kind_by_extension(p) == Some(DataKind::TetMesh) {
                        mesh::datasets::load_path_with(p, choice)
                    } else if crate::volume::sniff(&head) == Some(crate::volume::Format::Vti) {
                        mesh::vtu::read_vtu_with(p, choice)
                    } else {
                        mesh::vtk::read_vtk_legacy_with(p, choice)
                    };
                    let mesh = mesh.with_context(|| format!("loading dataset '{path}'"))?;
                    Ok(Dataset::from_loaded_mesh(mesh, false, path.to_string()))
                }
                None => anyhow::bail!(
                    "dataset '{path}': neither its content nor its extension is a format volbench reads; {}",
                    supported_formats()
                ),
            }
        }
    }
}

/// Load a tetrahedral mesh by name or path (kept for benches and tests).
pub fn load_mesh(spec: &str) -> Result<TetMesh> {
    match load(spec)?.data {
        DatasetData::TetMesh { mesh, .. } => Ok(mesh),
        DatasetData::Volume(_) => anyhow::bail!("'{spec}' is a volume, not a tetrahedral mesh"),
        DatasetData::Terrain(_) => anyhow::bail!("'{spec}' is a terrain, not a tetrahedral mesh"),
    }
}

/// The transfer function a volume is shown with: a shipped volume's preset
/// file (`data/tf/<name>.json`; every shipped volume has one), else (a
/// volume from a file) a generic ramp over its range (attenuation per
/// diagonal, as for meshes). A preset that is missing or cannot be used is
/// an error naming it, never a silent ramp.
pub fn volume_transfer_function(v: &Volume, named: Option<&str>) -> Result<TransferFunction> {
    let diag = v.bounds().diagonal().max(f64::MIN_POSITIVE);
    if let Some(name) = named {
        let path = crate::data_dir::data_dir().join("tf").join(format!("{name}.json"));
        let Some(path) = crate::scene::tf_file::preset_path(name) else {
            anyhow::bail!(
                "the preset transfer function of '{name}' ({}) is missing: a shipped volume is shown with its preset, \
                 not a generic ramp; restore the file, or give --tf FILE ({})",
                path.display(),
                crate::data_dir::search_note()
            );
        };
        return crate::scene::tf_file::load_tf(&path, v.range(), diag)
            .with_context(|| format!("the preset transfer function of '{name}' ({})", path.display()));
    }
    let (lo, hi) = crate::scene::effective_scalar_range(v.range().0, v.range().1);
    let stops = [(0.0, [0.2, 0.3, 1.0], 0.0), (0.3, [0.3, 1.0, 0.3], 2.0), (1.0, [1.0, 0.3, 0.1], 8.0)];
    Ok(TransferFunction {
        name: "generic-ramp".into(),
        points: stops
            .iter()
            .map(|&(t, color, depth)| ControlPoint { scalar: lo + t * (hi - lo), color, attenuation: depth / diag })
            .collect(),
    })
}

/// The transfer function a mesh is shown with: the named dataset's preset
/// (`named`: the name it was asked for), or a generic ramp for any other
/// mesh (a file called `bluntfin.vtk` is not the blunt fin). Attenuation is
/// given per mesh diagonal, so a preset reads the same whatever the units.
pub fn mesh_transfer_function(mesh: &TetMesh, named: Option<&str>) -> TransferFunction {
    // A constant field gets a widened range (the one rule `tf_file` uses
    // too), so the ramp has no step at the field's value.
    let (lo, hi) = crate::scene::effective_scalar_range(mesh.scalar_range().0, mesh.scalar_range().1);
    let diag = mesh.bounds().diagonal().max(f64::MIN_POSITIVE);
    // (relative scalar in [0,1], colour, optical depth across one diagonal)
    let stops: &[(f64, [f64; 3], f64)] = match named.unwrap_or("") {
        // Density: freestream (~1) almost clear; the bow shock and the
        // compression in front of the fin show as warm shells.
        "bluntfin" => &[
            (0.00, [0.10, 0.20, 0.90], 4.0),
            (0.12, [0.10, 0.50, 1.00], 1.0),
            (0.18, [0.20, 0.80, 0.60], 0.5),
            (0.30, [0.90, 0.90, 0.20], 8.0),
            (0.55, [1.00, 0.50, 0.10], 20.0),
            (1.00, [1.00, 0.10, 0.05], 40.0),
        ],
        // Velocity magnitude: the slow wake behind the post stands out blue,
        // the fast stream around it is faint.
        // Velocity magnitude (flow along +x, freestream ~1.1 = 0.8 of the
        // range): the no-slip walls (post and floor, ~0) stay clear, the slow
        // wake behind the post shows blue, the freestream is a faint haze and
        // the fast flow past the post's flanks (up to 1.39) glows orange.
        "oxygenpost" => &[
            (0.00, [0.10, 0.20, 0.60], 0.0),
            (0.04, [0.10, 0.30, 1.00], 0.0),
            (0.08, [0.10, 0.40, 1.00], 2.0),
            (0.30, [0.20, 0.90, 1.00], 8.0),
            (0.45, [0.30, 1.00, 0.60], 4.0),
            (0.55, [0.40, 0.80, 0.40], 0.2),
            (0.91, [0.90, 0.80, 0.30], 0.2),
            (0.95, [1.00, 0.50, 0.10], 6.0),
            (1.00, [1.00, 0.20, 0.05], 20.0),
        ],
        // Pressure on VTK's small tetrahedral post.
        "post-small" => &[
            (0.00, [0.10, 0.30, 1.00], 30.0),
            (0.25, [0.20, 0.70, 1.00], 12.0),
            (0.50, [0.30, 0.90, 0.40], 3.0),
            (0.75, [1.00, 0.80, 0.20], 1.5),
            (1.00, [1.00, 0.30, 0.10], 6.0),
        ],
        _ => &[
            (0.0, [0.2, 0.3, 1.0], 1.0),
            (0.5, [0.3, 1.0, 0.3], 4.0),
            (1.0, [1.0, 0.3, 0.1], 8.0),
        ],
    };
    TransferFunction {
        name: match named {
            Some(n) => format!("{n}-default"),
            None => "generic-ramp".into(),
        },
        points: stops
            .iter()
            .map(|&(t, color, depth)| ControlPoint { scalar: lo + t * (hi - lo), color, attenuation: depth / diag })
            .collect(),
    }
}
