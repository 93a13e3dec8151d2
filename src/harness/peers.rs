//! Peers measured in the same run (`volbench suite --peers vtk`): other
//! renderers given the same data, camera path, transfer function and image
//! size as volbench's methods, timed on the same machine in the same session
//! so that their frame times can be set beside volbench's as ratios.
//!
//! A peer is an external program (VTK's Python wheel in a private virtual
//! environment, installed by `scripts/install-vtk.sh`) driven through files:
//! volbench writes the dataset as a legacy VTK file ([`write_dataset`]) — or,
//! for a user's own file (`suite --data FILE`), names the original file for
//! the peer to read with its own reader ([`original_dataset`]), so that a
//! reading mistake on either side shows as a disagreement — and a scene
//! file (JSON, [`PeerScene`]), runs the peer's script once per renderer, and
//! reads back a result file ([`PeerResult`], checked before use) and the
//! reference view's image (raw RGBA8), which is compared with volbench's f64
//! reference like any run, and with volbench's own images of the same view. Peers are keyed by the kind of data they render, never by
//! volbench method names. Without `--peers` nothing here runs and nothing
//! Python is needed.
//!
//! **Transfer function.** volbench's transfer function gives colour and an
//! attenuation τ per unit length, both linear between control points; the
//! emission–absorption integral composites L·(1 − e^{−τ·Δs}). VTK takes an
//! "opacity" o per point and a unit distance d, read in one of two ways:
//! - [`OpacityModel::Attenuation`] (VTK's projected tetrahedra and its
//!   linear ray integrator for unstructured grids): o/d *is* τ. With
//!   d = 1/τ_max, o = τ·d ∈ [0, 1] at the same control points, linear in
//!   between as volbench's: the encoding is exact.
//! - [`OpacityModel::Correction`] (VTK's volume ray casters): a sample of
//!   length Δs gets α = 1 − (1 − o)^{Δs/d}, so o = 1 − e^{−τ·d} is exact at
//!   the points where it is given; between them VTK interpolates o, not τ,
//!   so the function is resampled at [`CORRECTION_SAMPLES`] evenly spaced
//!   scalars besides the control points (the difference is then far below
//!   the 8-bit framebuffer's resolution).
//!
//! What cannot be equal is the peers' own approximation and precision (VTK's
//! projected tetrahedra map colour and opacity to 8 bits per vertex and
//! average them over a tet; its framebuffer is 8 bits per channel), which is
//! what the error against the f64 reference measures.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use anyhow::{bail, Context as _, Result};
use serde::{Deserialize, Serialize};

use super::datasets::{Dataset, DatasetData};
use super::image::RgbaImage;
use super::run::RunConfig;
use super::stats::Summary as Stats;
use crate::algo::method::DataKind;
use crate::fsio;
use crate::scene::{Camera, TransferFunction};

/// The scene and result file formats (`format` and `version` fields).
pub const SCENE_FORMAT: &str = "volbench-peer-scene";
pub const RESULT_FORMAT: &str = "volbench-peer-result";
/// 2: the dataset may be a user's original file, with the scalar array,
/// its association and cell-data treatment named ([`PeerScalar`]).
pub const FORMAT_VERSION: u32 = 2;

/// Evenly spaced scalars the transfer function is resampled at for
/// [`OpacityModel::Correction`] (plus its control points).
pub const CORRECTION_SAMPLES: usize = 512;

/// How a peer renderer reads opacity (see the module note).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum OpacityModel {
    /// opacity / unit distance is the attenuation coefficient.
    Attenuation,
    /// opacity is per unit distance, corrected as 1 − (1 − o)^{Δs/d}.
    Correction,
}

/// One renderer of a peer: what it is called in results, the class it is,
/// the data it renders and how it reads opacity.
#[derive(Debug, Clone, Copy)]
pub struct PeerRenderer {
    pub name: &'static str,
    pub class: &'static str,
    pub kind: DataKind,
    pub opacity: OpacityModel,
}

/// A peer: a name (`--peers NAME`), its renderers, and how to run it.
#[derive(Debug)]
pub struct Peer {
    pub name: &'static str,
    pub renderers: &'static [PeerRenderer],
    /// The driver script, relative to the checkout.
    pub script: &'static str,
    /// The virtual environment's default folder, relative to the checkout,
    /// and the variable that overrides it.
    pub venv: &'static str,
    pub venv_env: &'static str,
    pub install: &'static str,
}

/// Every peer volbench knows.
pub const PEERS: &[Peer] = &[Peer {
    name: "vtk",
    renderers: &[
        PeerRenderer {
            name: "projected-tetrahedra",
            class: "vtkProjectedTetrahedraMapper",
            kind: DataKind::TetMesh,
            opacity: OpacityModel::Attenuation,
        },
        PeerRenderer {
            name: "unstructured-raycast",
            class: "vtkUnstructuredGridVolumeRayCastMapper",
            kind: DataKind::TetMesh,
            opacity: OpacityModel::Attenuation,
        },
        PeerRenderer { name: "gpu-raycast", class: "vtkGPUVolumeRayCastMapper", kind: DataKind::Volume, opacity: OpacityModel::Correction },
        PeerRenderer {
            name: "fixed-point-raycast",
            class: "vtkFixedPointVolumeRayCastMapper",
            kind: DataKind::Volume,
            opacity: OpacityModel::Correction,
        },
    ],
    script: "scripts/peers/vtk_peer.py",
    venv: ".venv-vtk",
    venv_env: "VOLBENCH_VTK_VENV",
    install: "bash scripts/install-vtk.sh",
}];

/// A peer ready to run: its interpreter and script were found.
#[derive(Debug, Clone)]
pub struct LocatedPeer {
    pub peer: &'static Peer,
    pub python: PathBuf,
    pub script: PathBuf,
}

impl LocatedPeer {
    /// The peer's renderers for a kind of data.
    pub fn renderers_for(&self, kind: DataKind) -> impl Iterator<Item = &'static PeerRenderer> {
        self.peer.renderers.iter().filter(move |r| r.kind == kind)
    }
}

/// Find `--peers NAME`'s interpreter and script, or say how to install them.
pub fn locate(name: &str) -> Result<LocatedPeer> {
    let Some(peer) = PEERS.iter().find(|p| p.name == name) else {
        bail!("--peers {name}: unknown peer (known: {})", PEERS.iter().map(|p| p.name).collect::<Vec<_>>().join(", "));
    };
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let venv = match std::env::var_os(peer.venv_env) {
        Some(v) if !v.is_empty() => PathBuf::from(v),
        _ => root.join(peer.venv),
    };
    let python = venv.join("bin").join("python");
    if !python.is_file() {
        bail!("--peers {name}: no Python environment at {} ({} sets another); run `{}` first", venv.display(), peer.venv_env, peer.install);
    }
    let script = root.join(peer.script);
    fsio::check_input(&script, "peer script", 1 << 20).with_context(|| format!("--peers {name}"))?;
    Ok(LocatedPeer { peer, python, script })
}

/// The transfer function in VTK's terms for one opacity model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PeerTransferFunction {
    pub name: String,
    pub opacity_model: String,
    pub unit_distance: f64,
    /// [scalar, r, g, b], scalars strictly increasing.
    pub color_points: Vec<[f64; 4]>,
    /// [scalar, opacity in [0, 1]], scalars strictly increasing.
    pub opacity_points: Vec<[f64; 2]>,
    /// volbench's own control points, for the record.
    pub volbench_points: Vec<crate::scene::ControlPoint>,
}

/// Scalars strictly increasing: a step (equal scalars) becomes a ramp one
/// part in 1e9 of the range wide (VTK keeps one point per scalar).
fn strictly_increasing(scalars: &mut [f64], range: f64) {
    let eps = range.abs().max(f64::MIN_POSITIVE) * 1e-9;
    for i in 1..scalars.len() {
        if scalars[i] <= scalars[i - 1] {
            scalars[i] = scalars[i - 1] + eps.max(scalars[i - 1].abs() * 1e-12);
        }
    }
}

/// Encode volbench's transfer function for a renderer that reads opacity as
/// `model` says (see the module note).
pub fn encode_transfer_function(tf: &TransferFunction, model: OpacityModel) -> Result<PeerTransferFunction> {
    anyhow::ensure!(!tf.points.is_empty(), "transfer function '{}' has no control points", tf.name);
    for p in &tf.points {
        anyhow::ensure!(
            p.scalar.is_finite() && p.attenuation.is_finite() && p.attenuation >= 0.0 && p.color.iter().all(|c| c.is_finite()),
            "transfer function '{}': control point at {} is not finite and non-negative; a peer cannot be given it",
            tf.name,
            p.scalar
        );
    }
    let tau_max = tf.points.iter().map(|p| p.attenuation).fold(0.0, f64::max);
    let unit_distance = if tau_max > 0.0 { 1.0 / tau_max } else { 1.0 };
    let (lo, hi) = tf.scalar_range();
    // The control points (steps keep both sides, in order), plus for the
    // correction model evenly spaced samples between them.
    let mut points: Vec<(f64, [f64; 3], f64)> = tf.points.iter().map(|p| (p.scalar, p.color, p.attenuation)).collect();
    if model == OpacityModel::Correction && hi > lo {
        for k in 0..=CORRECTION_SAMPLES {
            let s = lo + (hi - lo) * k as f64 / CORRECTION_SAMPLES as f64;
            if !tf.points.iter().any(|p| p.scalar == s) {
                let (c, tau) = tf.eval(s);
                points.push((s, c, tau));
            }
        }
        // Stable: equal scalars (a step's two sides) keep their order.
        points.sort_by(|a, b| a.0.total_cmp(&b.0));
    }
    let mut scalars: Vec<f64> = points.iter().map(|p| p.0).collect();
    let values: Vec<([f64; 3], f64)> = points.iter().map(|p| (p.1, p.2)).collect();
    strictly_increasing(&mut scalars, hi - lo);
    let opacity = |tau: f64| match model {
        OpacityModel::Attenuation => (tau * unit_distance).clamp(0.0, 1.0),
        OpacityModel::Correction => -(-tau * unit_distance).exp_m1(),
    };
    Ok(PeerTransferFunction {
        name: tf.name.clone(),
        opacity_model: serde_json::to_value(model)?.as_str().unwrap_or_default().to_string(),
        unit_distance,
        color_points: scalars.iter().zip(&values).map(|(&s, (c, _))| [s, c[0], c[1], c[2]]).collect(),
        opacity_points: scalars.iter().zip(&values).map(|(&s, &(_, tau))| [s, opacity(tau)]).collect(),
        volbench_points: tf.points.clone(),
    })
}

/// The dataset as the peer reads it.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct PeerDataset {
    pub name: String,
    pub kind: String,
    pub file: String,
    /// How to read `file`: volbench's export (`vtk-legacy-unstructured-grid`,
    /// `vtk-legacy-structured-points`), or a user's original file, one of
    /// [`ORIGINAL_FORMATS`].
    pub format: String,
    pub digest: String,
    /// `file` is the user's original file (not volbench's export).
    #[serde(default)]
    pub original: bool,
    /// A PLOT3D pair's solution (Q) file; `file` is its grid.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub solution_file: Option<String>,
    #[serde(default)]
    pub scalar: PeerScalar,
}

/// Which of the file's arrays is the scalar, and how it is rendered.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PeerScalar {
    /// The array by name (vectors by magnitude); `None`: the file's default
    /// as volbench's reader picks it (the active scalars, else the first
    /// point array: of any width in `.vtu`/`.pvtu`, one component in legacy
    /// `.vtk` and `.vti`).
    pub array: Option<String>,
    /// `point` or `cell`.
    pub association: String,
    /// Cell scalars: `constant` (one value per cell) or `average` (to the
    /// points, as `vtkCellDataToPointData`); `None` for point scalars.
    pub cell_data: Option<String>,
}

impl Default for PeerScalar {
    fn default() -> Self {
        PeerScalar { array: None, association: "point".into(), cell_data: None }
    }
}

/// The formats of users' files the peer reads with its own readers
/// (`scripts/peers/vtk_peer.py`): legacy `.vtk` (`vtkDataSetReader`), `.vtu`,
/// `.pvtu`, `.vti`, NRRD (`.nrrd`, `.nhdr`), NIfTI-1 (`.nii`, `.nii.gz`),
/// MetaImage (`.mhd`, `.mha`) and PLOT3D pairs.
pub const ORIGINAL_FORMATS: [&str; 8] = ["vtk-legacy", "vtu", "pvtu", "vti", "nrrd", "nifti", "metaimage", "plot3d"];

/// The peer's format key of a user's file: by extension, else by content.
fn original_format(path: &Path, kind: DataKind) -> Option<&'static str> {
    let file = path.file_name().map(|f| f.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
    let ext = file.rsplit_once('.').map(|(_, e)| e.to_string()).unwrap_or_default();
    let by_ext = match ext.as_str() {
        "vtk" => Some("vtk-legacy"),
        "vtu" => Some("vtu"),
        "pvtu" => Some("pvtu"),
        "vti" => Some("vti"),
        "nrrd" | "nhdr" => Some("nrrd"),
        "nii" => Some("nifti"),
        "gz" if file.ends_with(".nii.gz") => Some("nifti"),
        "mhd" | "mha" => Some("metaimage"),
        e if kind == DataKind::TetMesh && crate::mesh::datasets::PLOT3D_EXTENSIONS.contains(&e) => Some("plot3d"),
        _ => None,
    };
    by_ext.or_else(|| {
        use std::io::Read as _;
        let mut head = Vec::new();
        std::fs::File::open(path).ok()?.take(1 << 16).read_to_end(&mut head).ok()?;
        match crate::volume::sniff(&head)? {
            crate::volume::Format::Nrrd => Some("nrrd"),
            crate::volume::Format::Nifti => Some("nifti"),
            crate::volume::Format::VtkLegacy => Some("vtk-legacy"),
            crate::volume::Format::Vti if kind == DataKind::TetMesh => Some("vtu"),
            crate::volume::Format::Vti => Some("vti"),
            #[allow(unreachable_patterns)]
            _ => None,
        }
    })
}

/// A user's file (`source`: as `--data` gave it, `FILE` or `FILE#SCALAR`)
/// as the peer reads it: the original file and its format, and the scalar
/// volbench renders — the array named after `#`, else the one the dataset's
/// summary records (`scalar_array`), else the reader's default; its
/// association (`scalar_association`, default `point`) and cell-data
/// treatment (`cell_data`). `name` names it in the peer's files.
pub fn original_dataset(dataset: &Dataset, name: &str, source: &str) -> Result<PeerDataset> {
    let (file, array) = match source.rsplit_once('#') {
        Some((f, a)) if std::fs::symlink_metadata(source).is_err() => (f, Some(a.to_string())),
        _ => (source, None),
    };
    let path = Path::new(file);
    let kind = dataset.kind();
    anyhow::ensure!(kind != DataKind::Terrain, "'{file}': no peer renders terrains");
    let format = original_format(path, kind)
        .with_context(|| format!("'{file}': the peers have no reader for this file (they read {})", ORIGINAL_FORMATS.join(", ")))?;
    let absolute = |p: &Path| std::fs::canonicalize(p).unwrap_or_else(|_| p.to_path_buf()).to_string_lossy().into_owned();
    let (file, solution_file) = if format == "plot3d" {
        let (xyz, q) = crate::mesh::datasets::plot3d_pair(path)?;
        (absolute(&xyz), Some(absolute(&q)))
    } else {
        (absolute(path), None)
    };
    let stats = dataset.summary().stats;
    let text = |k: &str| stats.get(k).and_then(|v| v.as_str()).map(str::to_string);
    let association = text("scalar_association").unwrap_or_else(|| "point".into());
    anyhow::ensure!(association == "point" || association == "cell", "'{file}': scalar association '{association}' is neither point nor cell");
    let cell_data = if association == "cell" { Some(text("cell_data").unwrap_or_else(|| "constant".into())) } else { None };
    Ok(PeerDataset {
        name: name.to_string(),
        kind: kind.name().to_string(),
        file,
        format: format.to_string(),
        digest: dataset.digest.clone(),
        original: true,
        solution_file,
        scalar: PeerScalar { array: array.or_else(|| text("scalar_array")), association, cell_data },
    })
}

#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct PeerOutput {
    pub result: String,
    pub image: String,
}

impl PeerOutput {
    /// The result (`<stem>.json`) and image (`<stem>.rgba`) files in `dir`.
    pub fn in_dir(dir: &Path, stem: &str) -> Self {
        PeerOutput {
            result: dir.join(format!("{stem}.json")).to_string_lossy().into_owned(),
            image: dir.join(format!("{stem}.rgba")).to_string_lossy().into_owned(),
        }
    }
}

/// Everything a peer renderer is given (the scene file).
#[derive(Debug, Clone, Serialize)]
pub struct PeerScene {
    pub format: &'static str,
    pub version: u32,
    pub peer: &'static str,
    pub renderer: &'static str,
    pub dataset: PeerDataset,
    pub width: u32,
    pub height: u32,
    pub warmup: usize,
    pub frames: usize,
    /// One camera per warm-up and timed frame, in order (volbench's orbit).
    pub cameras: Vec<Camera>,
    /// The view whose image is compared with the reference (orbit angle 0).
    pub reference_camera: Camera,
    pub transfer_function: PeerTransferFunction,
    /// World distance between samples for volume ray casters: half the
    /// smallest voxel spacing (volbench's ray casters' default step).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sample_distance: Option<f64>,
    pub output: PeerOutput,
}

impl PeerScene {
    /// File stem of everything this scene writes: `<dataset>-peer-<peer>-<renderer>`.
    pub fn stem(&self) -> String {
        scene_stem(&self.dataset.name, self.peer, self.renderer)
    }
}

/// The scene a peer renderer is given for a dataset exported as `exported`:
/// the run's cameras (warm-up and timed frames, then the reference view),
/// size, the transfer function encoded for the renderer, outputs in `dir`.
pub fn scene(
    peer: &'static Peer,
    renderer: &'static PeerRenderer,
    dataset: &Dataset,
    tf: &TransferFunction,
    cfg: &RunConfig,
    exported: &PeerDataset,
    dir: &Path,
) -> Result<PeerScene> {
    cfg.validate()?;
    anyhow::ensure!(
        renderer.kind == dataset.kind(),
        "peer {}/{} renders {} data; '{}' is {}",
        peer.name,
        renderer.name,
        renderer.kind.name(),
        dataset.name,
        dataset.kind().name()
    );
    let stem = scene_stem(&exported.name, peer.name, renderer.name);
    Ok(PeerScene {
        format: SCENE_FORMAT,
        version: FORMAT_VERSION,
        peer: peer.name,
        renderer: renderer.name,
        dataset: exported.clone(),
        width: cfg.width,
        height: cfg.height,
        warmup: cfg.warmup,
        frames: cfg.frames,
        cameras: (0..cfg.warmup + cfg.frames).map(|f| cfg.camera(dataset, f)).collect(),
        reference_camera: cfg.camera(dataset, 0),
        transfer_function: encode_transfer_function(tf, renderer.opacity)?,
        sample_distance: sample_distance(dataset),
        output: PeerOutput::in_dir(dir, &stem),
    })
}

/// File stem of everything a scene writes: `<dataset>-peer-<peer>-<renderer>`.
fn scene_stem(dataset: &str, peer: &str, renderer: &str) -> String {
    format!("{dataset}-peer-{peer}-{renderer}")
}

/// Write the dataset as a binary legacy VTK file the peer reads: an
/// unstructured grid of tetrahedra with point scalars (f64), or structured
/// points with f32 samples (exact for every sample type volbench loads).
pub fn write_dataset(dataset: &Dataset, path: &Path) -> Result<PeerDataset> {
    let format = match &dataset.data {
        DatasetData::TetMesh { mesh, .. } => {
            write_tet_mesh(mesh, &format!("volbench peer copy of {}", dataset.name), path)?;
            "vtk-legacy-unstructured-grid"
        }
        DatasetData::Volume(v) => {
            // A method took the samples and reading them again failed
            // (`Dataset::run_handing_over`): no file of a different length.
            anyhow::ensure!(
                v.samples().len() == v.len(),
                "volume '{}': its samples were handed to a method and could not be read again, so it is not exported to the peers",
                dataset.name
            );
            fsio::write_output_with(path, |w| {
                let [nx, ny, nz] = v.dims();
                let [sx, sy, sz] = v.spacing();
                let [ox, oy, oz] = v.origin();
                write!(
                    w,
                    "# vtk DataFile Version 3.0\nvolbench peer copy of {}\nBINARY\nDATASET STRUCTURED_POINTS\nDIMENSIONS {nx} {ny} {nz}\n\
                     SPACING {sx:e} {sy:e} {sz:e}\nORIGIN {ox:e} {oy:e} {oz:e}\nPOINT_DATA {}\nSCALARS scalars float 1\nLOOKUP_TABLE default\n",
                    dataset.name,
                    v.len()
                )?;
                for s in v.to_f32() {
                    w.write_all(&s.to_be_bytes())?;
                }
                w.write_all(b"\n")?;
                Ok(())
            })?;
            "vtk-legacy-structured-points"
        }
        DatasetData::Terrain(_) => anyhow::bail!("'{}': no peer renders terrains, so none is exported", dataset.name),
    };
    Ok(PeerDataset {
        name: dataset.name.clone(),
        kind: dataset.kind().name().to_string(),
        file: path.to_string_lossy().into_owned(),
        format: format.into(),
        digest: dataset.digest.clone(),
        original: false,
        solution_file: None,
        // The export's one array: `scalars`, point data.
        scalar: PeerScalar { array: Some("scalars".into()), ..PeerScalar::default() },
    })
}

/// The bytes [`write_tet_mesh`] writes for `points` points and `tets`
/// tets under `title` (the file's size, known before writing it).
pub fn tet_mesh_file_bytes(points: u128, tets: u128, title: &str) -> u128 {
    let digits = |n: u128| n.to_string().len() as u128;
    let text = "# vtk DataFile Version 3.0\n\nBINARY\nDATASET UNSTRUCTURED_GRID\nPOINTS  double\n".len()
        + "\nCELLS  \n".len()
        + "\nCELL_TYPES \n".len()
        + "\nPOINT_DATA \nSCALARS scalars double 1\nLOOKUP_TABLE default\n".len()
        + "\n".len()
        + title.len();
    text as u128 + 2 * digits(points) + 2 * digits(tets) + digits(5 * tets) + points * (24 + 8) + tets * (20 + 4)
}

/// `mesh` as a binary legacy VTK unstructured grid of tetrahedra with f64
/// point scalars, titled `title` (what every VTK reader and volbench read).
pub fn write_tet_mesh(mesh: &crate::mesh::TetMesh, title: &str, path: &Path) -> Result<()> {
    fsio::write_output_with(path, |w| {
        write!(
            w,
            "# vtk DataFile Version 3.0\n{}\nBINARY\nDATASET UNSTRUCTURED_GRID\nPOINTS {} double\n",
            title,
            mesh.points.len()
        )?;
        for p in &mesh.points {
            for c in p {
                w.write_all(&c.to_be_bytes())?;
            }
        }
        let size = mesh.tets.len().checked_mul(5).context("too many tets for a VTK file")?;
        write!(w, "\nCELLS {} {size}\n", mesh.tets.len())?;
        for t in &mesh.tets {
            w.write_all(&4i32.to_be_bytes())?;
            for &i in t {
                let i = i32::try_from(i).context("a point index beyond VTK's 32-bit legacy format")?;
                w.write_all(&i.to_be_bytes())?;
            }
        }
        write!(w, "\nCELL_TYPES {}\n", mesh.tets.len())?;
        for _ in &mesh.tets {
            w.write_all(&10i32.to_be_bytes())?;
        }
        write!(w, "\nPOINT_DATA {}\nSCALARS scalars double 1\nLOOKUP_TABLE default\n", mesh.scalars.len())?;
        for s in &mesh.scalars {
            w.write_all(&s.to_be_bytes())?;
        }
        w.write_all(b"\n")?;
        Ok(())
    })
}

/// The peer's sample distance for a dataset: half the smallest voxel
/// spacing for volumes, none for meshes.
pub fn sample_distance(dataset: &Dataset) -> Option<f64> {
    match &dataset.data {
        DatasetData::Volume(v) => Some(0.5 * v.spacing().into_iter().fold(f64::INFINITY, f64::min)),
        DatasetData::TetMesh { .. } | DatasetData::Terrain(_) => None,
    }
}

/// Image section of a peer result.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PeerImage {
    pub file: String,
    pub width: u32,
    pub height: u32,
    pub format: String,
    pub rows: String,
}

/// What a peer writes back (the result file), checked by [`parse_result`].
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PeerResult {
    pub format: String,
    pub version: u32,
    pub peer: String,
    pub renderer: String,
    pub class: String,
    pub library_version: String,
    pub window: String,
    pub gl_renderer: String,
    pub load_ms: f64,
    pub setup_ms: f64,
    pub warmup_ms: Vec<f64>,
    pub frame_ms: Vec<f64>,
    pub image: PeerImage,
}

/// Parse and check a peer's result against the scene it was given: format
/// and version, the renderer asked for, one finite non-negative time per
/// frame, the image's size and layout. `what` names the file in errors.
pub fn parse_result(text: &str, scene: &PeerScene, what: &str) -> Result<PeerResult> {
    let r: PeerResult = serde_json::from_str(text).with_context(|| format!("{what}: not a peer result"))?;
    anyhow::ensure!(
        r.format == RESULT_FORMAT && r.version == FORMAT_VERSION,
        "{what}: format '{}' version {}, expected '{RESULT_FORMAT}' version {FORMAT_VERSION}",
        r.format,
        r.version
    );
    anyhow::ensure!(
        r.peer == scene.peer && r.renderer == scene.renderer,
        "{what}: result of {}/{}, but {}/{} was asked for",
        r.peer,
        r.renderer,
        scene.peer,
        scene.renderer
    );
    anyhow::ensure!(
        r.frame_ms.len() == scene.frames && r.warmup_ms.len() == scene.warmup,
        "{what}: {} timed and {} warm-up frames, expected {} and {}",
        r.frame_ms.len(),
        r.warmup_ms.len(),
        scene.frames,
        scene.warmup
    );
    for (name, v) in r.frame_ms.iter().chain(&r.warmup_ms).map(|v| ("frame time", v)).chain([("load_ms", &r.load_ms), ("setup_ms", &r.setup_ms)]) {
        anyhow::ensure!(v.is_finite() && *v >= 0.0, "{what}: {name} {v} is not a finite non-negative number of milliseconds");
    }
    let i = &r.image;
    anyhow::ensure!(
        i.width == scene.width && i.height == scene.height,
        "{what}: image {}x{}, expected {}x{}",
        i.width,
        i.height,
        scene.width,
        scene.height
    );
    anyhow::ensure!(i.format == "rgba8" && i.rows == "top-down", "{what}: image format '{}' rows '{}', expected rgba8 top-down", i.format, i.rows);
    let expected = Path::new(&scene.output.image).file_name().map(|f| f.to_string_lossy().into_owned());
    anyhow::ensure!(Some(&i.file) == expected.as_ref(), "{what}: image file '{}' is not the one asked for", i.file);
    Ok(r)
}

/// Read the peer's raw RGBA8 image (top row first) as volbench's image:
/// the peer's framebuffer holds colour composited over transparent black,
/// i.e. premultiplied, as volbench's images are.
pub fn read_image(path: &Path, width: u32, height: u32) -> Result<RgbaImage> {
    let n = (width as u64).checked_mul(height as u64).and_then(|n| n.checked_mul(4)).context("peer image size overflows")?;
    let bytes = fsio::read_input(path, "peer image", n)?;
    anyhow::ensure!(bytes.len() as u64 == n, "{}: {} bytes, expected {n} for a {width}x{height} RGBA8 image", path.display(), bytes.len());
    let pixels = bytes.chunks_exact(4).map(|p| [p[0], p[1], p[2], p[3]].map(|c| f32::from(c) / 255.0)).collect();
    Ok(RgbaImage { width, height, pixels })
}

/// A peer process may take this long before it is stopped (seconds;
/// `VOLBENCH_PEER_TIMEOUT_S` overrides).
pub const DEFAULT_TIMEOUT_S: u64 = 900;

fn timeout() -> Result<Duration> {
    Ok(Duration::from_secs(crate::switches::int(crate::switches::PEER_TIMEOUT_S)?.unwrap_or(DEFAULT_TIMEOUT_S)))
}

/// Run one peer renderer on a scene written to `scene_path`; returns the
/// checked result and the image.
pub fn run_peer(peer: &LocatedPeer, scene: &PeerScene, scene_path: &Path) -> Result<(PeerResult, RgbaImage)> {
    fsio::write_output(scene_path, &serde_json::to_vec_pretty(scene)?)?;
    let limit = timeout()?;
    // In a process group of its own with a deadline, its output kept head
    // and tail (`child::run`): what it starts (and what keeps its stderr
    // open) is stopped with it, and a chatty peer costs kilobytes.
    let what = format!("{} {}", peer.peer.name, scene.renderer);
    let mut cmd = Command::new(&peer.python);
    cmd.arg(&peer.script).arg("--scene").arg(scene_path).env("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow");
    let finished = super::child::run(&mut cmd, &what, limit, crate::switches::PEER_TIMEOUT_S, None)
        .with_context(|| format!("running {} {}", peer.python.display(), peer.script.display()))?;
    let (status, err) = (finished.status, finished.stderr.text());
    // The last lines say why (VTK's own warnings come first).
    let tail: Vec<&str> = err.lines().filter(|l| !l.trim().is_empty()).collect();
    let tail = tail[tail.len().saturating_sub(3)..].join(" / ");
    if !status.success() {
        let how = match status.code() {
            Some(c) => format!("exit status {c}"),
            None => {
                #[cfg(unix)]
                {
                    use std::os::unix::process::ExitStatusExt as _;
                    format!("killed by signal {}", status.signal().unwrap_or(0))
                }
                #[cfg(not(unix))]
                {
                    "killed".to_string()
                }
            }
        };
        bail!("{} {} failed ({how}){}", peer.peer.name, scene.renderer, if tail.is_empty() { String::new() } else { format!(": {tail}") });
    }
    let result_path = Path::new(&scene.output.result);
    let text = fsio::read_input_text(result_path, "peer result", 16 << 20)?;
    let result = parse_result(&text, scene, &result_path.display().to_string())?;
    let image = read_image(Path::new(&scene.output.image), scene.width, scene.height)?;
    Ok((result, image))
}

/// One peer row of the suite: clearly a peer (`peer`, `renderer`, `class`),
/// never a volbench method.
#[derive(Debug, Clone, Serialize)]
pub struct PeerRow {
    pub peer: String,
    pub renderer: String,
    pub class: String,
    pub dataset: String,
    pub status: &'static str,
    pub message: Option<String>,
    /// Position in the suite's run order (peers alternate with volbench's runs).
    pub sequence: usize,
    pub library_version: Option<String>,
    pub gl_renderer: Option<String>,
    pub opacity_model: Option<String>,
    /// Median/min/max/mean of the timed frames (Render + WaitForCompletion).
    pub frame_ms: Option<Stats>,
    pub frame_samples_ms: Vec<f64>,
    pub setup_ms: Option<f64>,
    pub error: Option<super::image::ImageError>,
    pub covered_pixels: Option<usize>,
    /// What the peer read: `export` (volbench's copy) or the original
    /// file's format ([`ORIGINAL_FORMATS`]).
    pub input: Option<String>,
    /// The peer's reference-view image against each volbench run's of the
    /// same view on the same dataset (standard scene).
    pub vs_volbench: Vec<ImageAgreement>,
}

/// A peer's image against one volbench run's image of the same view.
#[derive(Debug, Clone, Serialize)]
pub struct ImageAgreement {
    /// The volbench run (`PlannedRun::label`).
    pub label: String,
    pub rmse: f64,
    pub max_abs: f64,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::ControlPoint;

    fn tf() -> TransferFunction {
        TransferFunction {
            name: "t".into(),
            points: vec![
                ControlPoint { scalar: 0.0, color: [0.1, 0.2, 0.3], attenuation: 0.0 },
                ControlPoint { scalar: 1.0, color: [1.0, 0.0, 0.0], attenuation: 4.0 },
                ControlPoint { scalar: 1.0, color: [0.0, 1.0, 0.0], attenuation: 2.0 },
                ControlPoint { scalar: 3.0, color: [0.0, 0.0, 1.0], attenuation: 8.0 },
            ],
        }
    }

    #[test]
    fn attenuation_encoding_is_tau_times_unit_distance_at_the_control_points() {
        let e = encode_transfer_function(&tf(), OpacityModel::Attenuation).unwrap();
        assert_eq!(e.unit_distance, 1.0 / 8.0);
        assert_eq!(e.opacity_points.len(), 4);
        let o: Vec<f64> = e.opacity_points.iter().map(|p| p[1]).collect();
        assert_eq!(o, [0.0, 0.5, 0.25, 1.0]);
        // The step keeps both sides, a hair apart and in order.
        assert!(e.opacity_points.windows(2).all(|w| w[1][0] > w[0][0]));
        assert!(e.opacity_points[2][0] - 1.0 < 1e-8);
        assert_eq!(e.color_points[2], [e.opacity_points[2][0], 0.0, 1.0, 0.0]);
    }

    #[test]
    fn correction_encoding_reproduces_the_optical_depth_between_points() {
        let t = tf();
        let e = encode_transfer_function(&t, OpacityModel::Correction).unwrap();
        assert!(e.opacity_points.len() > CORRECTION_SAMPLES);
        assert!(e.opacity_points.windows(2).all(|w| w[1][0] > w[0][0]));
        // Linear interpolation of o between the points, read back as tau,
        // matches volbench's tau within 1e-3 relative away from the step.
        for k in 0..300 {
            let s = 0.01 * k as f64 + 0.005;
            if (s - 1.0).abs() < 0.01 {
                continue;
            }
            let i = e.opacity_points.partition_point(|p| p[0] <= s);
            let (a, b) = (e.opacity_points[i - 1], e.opacity_points[i]);
            let o = a[1] + (b[1] - a[1]) * (s - a[0]) / (b[0] - a[0]);
            let tau = -(1.0 - o).ln() / e.unit_distance;
            let want = t.eval(s).1;
            assert!((tau - want).abs() <= 1e-3 * want.max(1.0), "s={s}: {tau} vs {want}");
        }
    }

    #[test]
    fn a_transparent_or_bad_transfer_function_is_handled() {
        let e = encode_transfer_function(&TransferFunction::constant([1.0; 3], 0.0), OpacityModel::Correction).unwrap();
        assert_eq!((e.unit_distance, e.opacity_points.clone()), (1.0, vec![[0.0, 0.0]]));
        let mut bad = tf();
        bad.points[1].attenuation = f64::INFINITY;
        let err = encode_transfer_function(&bad, OpacityModel::Attenuation).unwrap_err().to_string();
        assert!(err.contains("not finite"), "{err}");
    }

    #[test]
    fn a_volume_whose_samples_were_taken_is_not_exported() {
        let v = crate::volume::Volume::new("t", "t", [2, 2, 2], [1.0; 3], [0.0; 3], crate::volume::Samples::U8(vec![1; 8])).unwrap();
        let mut d = Dataset::from_volume(v, false, "t".into());
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.vtk");
        write_dataset(&d, &path).unwrap();
        std::fs::remove_file(&path).unwrap();
        let DatasetData::Volume(v) = &mut d.data else { unreachable!() };
        drop(v.take_samples());
        let err = write_dataset(&d, &path).unwrap_err().to_string();
        assert!(err.contains("could not be read again"), "{err}");
        assert!(!path.exists(), "no file written");
    }
}
