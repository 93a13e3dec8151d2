//! Regular-grid GPU ray casting (SPEC §3, the lab of `seeds/004_*`): two
//! registered methods sharing one march (`shaders/raycast/common.glsl`).
//!
//! - `raycast-fragment` ([`fragment`]): the lab's three passes. The bounding
//!   box's front faces are drawn into one RGBA32F target and its back faces
//!   into another (entry and exit points of every pixel's ray, in voxel
//!   coordinates), then a full-screen pass (scissored to the box's pixels,
//!   [`BoxOnScreen`]) marches each pixel from entry to exit. The eye inside
//!   the box clips the front faces away: the ray then starts on the near
//!   plane.
//! - `raycast-compute` ([`compute`]): one compute pass; each invocation
//!   clips its pixel's ray (near to far plane) to the box analytically and
//!   runs the same march, writing the runner's target as a storage image;
//!   only the tiles over the box's pixels are dispatched, their rows
//!   interleaved over the device's runs of workgroups
//!   (`algo::screen::interleaved_rows`).
//!
//! **Conventions** (the f64 reference's, `reference::volume`): node-centred
//! samples, sample (i, j, k) at `Volume::position(i, j, k)`; voxel
//! coordinates u = (p − origin) / spacing, the box is [0, dims − 1]; the 3D
//! texture has texel centres at the samples (texture coordinate
//! (u + 0.5) / dims). Anisotropic spacing is honoured by marching in voxel
//! coordinates and converting each step to its world length for opacity.
//!
//! **March.** A segment of L voxels is cut into n = ⌈L / step⌉ equal steps
//! (so no step exceeds `step` and the last one ends exactly at the exit),
//! sampled at their middles (`integrator=point`), classified through a 1D
//! table of colour and attenuation τ (f32, [`TABLE_SIZE`] entries over the
//! volume's value range; with `reads=loads|quads` read with two loads and
//! blended in f32, as the volume, and the brick map read as words: on
//! lavapipe a texture lookup is an out-of-line call around which the march
//! spills every live SIMD register), with opacity 1 − exp(−τ·Δs_world): the lab's
//! α' = 1 − (1 − α)^{Δs/Δs0} with α given per unit length. Front to back,
//! premultiplied. `integrator=preint` looks segments up in a 2D
//! pre-integration table over (front, back) scalar (Engel, Kraus, Ertl 2001)
//! built in f64 with the exact segment integral (`algo::segment`, not the
//! CPU reference's code) for a segment of
//! [`preint_length`] world units; optical depth is scaled to the actual step
//! (exact), colour per unit opacity is kept (exact when the world step equals
//! the table's length: along the axis of smallest spacing at the full step).
//! A segment's end scalars are corrected for curvature: the parabola through
//! the segment's two samples and the one before has, over the segment, the
//! linear mean minus D/12 (D the second difference), and both ends are moved
//! by that. Without it the linear segment's error in the mean scalar
//! (s''h²/12) is twice the midpoint rule's, and on the chest CT point
//! sampling beat pre-integration at every step (RMSE 1.03e-2 against 6.3e-3
//! at step 1); with it pre-integration is ahead up to step 1 (README).
//!
//! **Early termination and skipping.** Once the ray's opacity passes `ert`
//! (run-time; `ert=1` never triggers) the rest of the ray is not dropped (the
//! lab's rule, which on the chest CT changed the image by RMSE 4e-3: the
//! dropped 1 − ert is up to 5% of a pixel) but estimated: it is marched with
//! 4 steps per sample (`TAIL_STRIDE` in common.glsl) until the remaining transmittance is below
//! 1% of 1 − ert, then the ray stops. The error is then at most 1% of 1 − ert
//! plus the coarse march's error on a contribution of at most 1 − ert.
//!
//! **Empty-space skipping** (`skip=on`): the volume is cut into bricks of
//! `brick`³ voxels (option, default 2: the fastest on the chest CT, README
//! "Ray casting at its speed limit"), each flagged on the
//! CPU when the transfer function has attenuation somewhere over its sample
//! range (its samples and the next layer: the trilinear neighbourhood;
//! [`bricks::attenuating`]). A point sample in an unflagged
//! brick reads only samples whose attenuation is zero, so it can be stepped
//! over and the image is unchanged. For `preint` the flags are dilated by
//! ⌈step / (2·brick)⌉ bricks, so a segment whose middle lies in an unflagged
//! brick lies where the attenuation is zero everywhere. Every unflagged brick
//! also holds its Chebyshev distance d to the nearest flagged brick
//! ([`bricks::chebyshev_in_place`]): the cube of 2d − 1 bricks around it is empty and
//! the march leaps to the cube's exit in one iteration. Leaping is what makes
//! small bricks pay: on llvmpipe a skipped brick costs a loop iteration as
//! dear as a sample (both sides of every branch run), and with one iteration
//! per brick 2³-voxel bricks cost more than the samples they save. On the
//! chest CT (README) 2³ bricks with leaps take 8.1 M samples and 2.2 M leaps
//! per frame where 8³ bricks, one by one, took 14.0 M and 1.7 M. The grid is
//! rebuilt whenever the transfer function changes (a method is built per
//! transfer function). The ray's empty ends are leapt over in two loops of
//! their own before the march (`trim_empty_ends` in common.glsl): forward
//! from the first step to the first visible brick, backward from the last
//! step to the last one (not with `adaptive`, whose key counts the runs
//! near visible bricks in the march's order; its forward loop keeps the
//! key's bookkeeping). In the march's loop a leap costs an iteration as
//! dear as a sample; in those loops only the lookup. The segments keep the
//! lengths the whole ray gives them, so the image is unchanged.
//!
//! **Coarse steps in thin matter** (`coarse=A`, off by default; needs
//! `skip=on`, not with `adaptive`). A brick is dense when the transfer
//! function's attenuation over its sample range exceeds the τ at which
//! [`COARSE_STRIDE`] steps of `step` voxels along the axis of largest
//! spacing reach optical depth A ([`bricks::LayerFlags::dense`]). Each
//! brick's map entry gains a second byte, its Chebyshev distance to the
//! nearest dense brick (the map is then two bytes a brick). A visible
//! brick at distance d ≥ 1 from a dense one is the centre of a cube of
//! 2d − 1 bricks with none: the march takes the steps up to the cube's
//! exit [`COARSE_STRIDE`] at a time, one sample at their middle, without
//! looking their bricks up (empty bricks inside are sampled, not leapt).
//! So no coarse segment has a step middle in a dense brick: thin matter
//! (the chest CT's soft tissue) is sampled a third as often, opaque
//! structure (bone, vessels) at every step. A coarse segment's optical
//! depth is at most A, so its opacity is less; the family's error bound
//! adds A (measured: 4.4e-3 at A = 0.1, `tests/raycast.rs`). It is the
//! homogeneity idea of Danskin & Hanrahan (1992), "Fast algorithms for
//! volume ray tracing", with the bound taken from the transfer function.
//!
//! **Lighting** (`shade=on`, lab 6): Blinn-Phong with the central-difference
//! gradient (±1 voxel) as normal, ambient 0.3, diffuse 0.7, specular 0.25,
//! shininess 30; a headlight raised above the view direction. The lab
//! transforms eye and light into texture space; with anisotropic spacing
//! texture space is not isotropic, so here the gradient is converted to world
//! units (divided by the spacing) and light and eye directions are given in
//! world axes: the same angles as in world space. Only colour is shaded,
//! opacity is not.
//!
//! **Counts.** Every ray adds its samples to a device counter (atomics; also
//! the largest per ray, bricks stepped over, leaps and of them those over
//! the ray's empty ends, and rays), read back after the frame: `work`
//! reports them. Bricks stepped over by a leap are counted as the bricks the
//! skipped stretch of the ray passes through. The march's loop runs about
//! samples + leaps − leaps_at_ends iterations a ray.

pub mod bricks;
pub mod compute;
pub mod fragment;

use std::sync::Arc;
use std::time::Instant;

use anyhow::{bail, Context as _, Result};
use glam::{DMat4, DVec3, Vec3};
use serde_json::json;

use super::method::{Family, OptionSpec, Options, Published, PublishedFigure, View, Work};
use super::segment::integrate_segment;
use super::settings::{choice, flag, float, int, MethodSettings};
use crate::scene::TransferFunction;
use crate::volume::{Samples, Volume};
use crate::vk::{
    upload_static_texels, upload_texture, upload_texture_with, Blend, Buffer, BufferDesc, ColorTarget, CommandRecorder, ComputePipelineKey, Context,
    DescriptorKind, DescriptorResource, DescriptorSet, DescriptorSetDesc, GraphicsPipelineKey, GraphicsState, PipelineKey, Sampler, ShaderKey, ShaderStage,
    TexelBuffer, TextureDesc, UploadClass, UploadCounter,
};
use crate::vk::{BufferUsage, Cull, Filter, Format, Stages, Topology, Winding};

/// Transfer-function table entries (1D) and pre-integration table side (2D).
pub const TABLE_SIZE: usize = 1024;
pub const PREINT_SIZE: usize = 256;

crate::choices! {
    /// How a ray's samples are turned into colour and opacity.
    pub enum RayIntegrator {
        /// Point samples at each step's middle (the lab).
        Point = "point",
        /// Pre-integrated segments (Engel, Kraus, Ertl 2001).
        Preint = "preint",
    }
}

crate::choices! {
    /// How the shader reads the volume's trilinear field.
    pub enum VolumeReads {
        /// Eight texel loads blended in the shader on a CPU device (lavapipe),
        /// the texture unit's filter elsewhere.
        Auto = "auto",
        /// The sampler's trilinear filter (`textureLod`).
        Texture = "texture",
        /// Eight `imageLoad`s blended in f32 in the shader.
        Loads = "loads",
        /// Two `imageLoad`s of four samples each (every texel holds its
        /// sample and the +x, +y and +x+y neighbours), blended as `loads`.
        Quads = "quads",
    }
}

crate::settings! {
    /// The options both variants share, as typed values.
    pub struct Settings {
        step: f64 = "0.5", float(0.05, 8.0), run, "voxels", "largest distance between samples along a ray, in voxel units";
        ert: f64 = "0.95", float(0.5, 1.0), run, "",
            "early ray termination: stop once the accumulated opacity passes this (1 = off)";
        shade: bool = "off", flag(), build, "", "Blinn-Phong lighting from central-difference gradients";
        integrator: RayIntegrator = "point", choice::<RayIntegrator>(), build, "",
            "point samples (the lab) or pre-integrated segments (Engel, Kraus, Ertl 2001)";
        skip: bool = "on", flag(), build, "",
            "empty-space skipping: bricks classified against the transfer function, leaps over empty cubes of bricks";
        brick: usize = "2", int(1, 64), run, "voxels", "edge of the empty-space skipping bricks";
        reads: VolumeReads = "auto", choice::<VolumeReads>(), build, "",
            "how a sample reads the volume: texture (the sampler's trilinear filter), loads (eight texel loads \
             blended in f32 in the shader: on lavapipe the sampler is an out-of-line call with 8-bit weights), \
             quads (two loads of four samples each, blended as loads: the texture holds each sample with its +x, +y \
             and +x+y neighbours, 4x the bytes, beyond the memory bound of twice the samples), auto (loads on a CPU \
             device, texture elsewhere); the same field every way. With loads and quads the transfer-function table \
             and the brick map are read with loads too (the table blended in f32)";
        adaptive: f64 = "0", float(0.0, 0.25), build, "TOL", crate::algo::adaptive::HELP;
        coarse: f64 = "0", float(0.0, 1.0), build, "optical depth",
            "coarse steps where the matter is thin (0 = off; needs skip=on, not with adaptive): around a visible \
             brick, the cube of bricks on which the transfer function's attenuation keeps a segment of 3 steps' \
             world length below this optical depth is marched with one sample per 3 steps (module note)";
    }
    impl {
        fn check(&self) -> Result<()> {
            if self.coarse > 0.0 {
                anyhow::ensure!(self.skip, "coarse={}: needs skip=on (the thin cubes are found in the skipping bricks' map)", self.coarse);
                anyhow::ensure!(
                    self.adaptive == 0.0,
                    "coarse={} with adaptive={}: not combined (the refinement's structural key is read at every brick the march \
                     looks up, and a coarse cube is passed without looking its bricks up)",
                    self.coarse,
                    self.adaptive
                );
            }
            Ok(())
        }
    }
}

/// Steps one coarse sample covers (option `coarse`).
pub const COARSE_STRIDE: usize = 3;
/// [`COARSE_STRIDE`] as the shader's define.
const COARSE_STRIDE_DEFINE: &str = "3";
const _: () = assert!(COARSE_STRIDE_DEFINE.len() == 1 && COARSE_STRIDE_DEFINE.as_bytes()[0] == b'0' + COARSE_STRIDE as u8);

/// Both variants' options.
pub const OPTIONS: &[OptionSpec] = Settings::OPTIONS;

/// Sweep: step size x integrator, and at one step per integrator skipping
/// and early termination each off and both off (their speed-ups and image
/// differences measured in the same run); 8^3 bricks (the earlier default)
/// beside the default 2^3.
pub const SWEEP: &[&str] = &[
    "step=0.25",
    "step=0.5",
    "step=1",
    "step=2",
    "step=0.25,integrator=preint",
    "step=0.5,integrator=preint",
    "step=1,integrator=preint",
    "step=2,integrator=preint",
    "step=0.5,skip=off",
    "step=0.5,ert=1",
    "step=0.5,skip=off,ert=1",
    "step=1,integrator=preint,skip=off",
    "step=1,integrator=preint,ert=1",
    "step=1,integrator=preint,skip=off,ert=1",
    "step=0.5,brick=8",
];
pub const COMPARE: &[&str] = &["", "shade=on", "integrator=preint,step=1"];
/// The suite: besides the defaults (half-voxel steps), one sample per voxel
/// and one per 1.25 voxels, where point sampling still has about half and
/// three quarters of the error of VTK's CPU fixed-point ray caster at its
/// half-spacing step (README, "Peers"): the report compares speed at
/// matched error with it, and two points near its error sample the
/// time-error front where the comparison is made. These fast points read
/// the volume as quads (`reads=quads`: two loads a sample for 4x the
/// texture's bytes, a user's trade of memory for speed; the same image).
pub const SUITE: &[&str] = &["step=1,reads=quads", "step=1.25,reads=quads"];
/// Stress: the defaults, pre-integration, and skipping and termination off
/// (lighting is not compared: the reference does not shade).
pub const STRESS: &[&str] = &["", "integrator=preint", "skip=off,ert=1"];
/// `a` then `b`, as one array (the compute variant's lists extend the shared ones).
const fn joined<const N: usize>(a: &[&'static str], b: &[&'static str]) -> [&'static str; N] {
    assert!(a.len() + b.len() == N, "joined: N must be the two lengths' sum");
    let mut out = [""; N];
    let mut i = 0;
    while i < a.len() {
        out[i] = a[i];
        i += 1;
    }
    let mut j = 0;
    while j < b.len() {
        out[a.len() + j] = b[j];
        j += 1;
    }
    out
}

/// Adaptive refinement's tolerances in the suite (about 4/255 and 12/255,
/// the same on every volume, and about 8/255 over steps of 1.25 voxels)
/// and in the sweep (`pareto`).
const ADAPTIVE_SUITE: &[&str] = &["adaptive=0.016,reads=quads", "adaptive=0.048,reads=quads", "step=1.25,adaptive=0.032,reads=quads"];
/// Thin matter marched coarse (`coarse=0.1`) at the suite's larger step:
/// on a volume with much of it (the chest CT's soft tissue) a third fewer
/// samples for a quarter more error, elsewhere about the plain row. Run by
/// the compute variant only (the fragment variant marches the same way;
/// CI's time is near its limit). Both read paths: which is faster depends
/// on the CPU under lavapipe (on the chest CT quads won on one machine by
/// fewer instructions, loads on another, an AVX-512 EPYC whose 32 MB L3
/// holds the 8.7 MB volume but not its 35 MB of quads: results/HISTORY.md).
const COARSE_SUITE: &[&str] = &["step=1.25,reads=quads,coarse=0.1", "step=1.25,reads=loads,coarse=0.1"];
const ADAPTIVE_SWEEP: &[&str] = &["adaptive=0.008", "adaptive=0.016", "adaptive=0.032", "adaptive=0.064"];
const SUITE_COMPUTE_EXTRA: [&str; COARSE_SUITE.len() + ADAPTIVE_SUITE.len()] = joined(COARSE_SUITE, ADAPTIVE_SUITE);
const SUITE_COMPUTE_LIST: [&str; SUITE.len() + SUITE_COMPUTE_EXTRA.len()] = joined(SUITE, &SUITE_COMPUTE_EXTRA);
const STRESS_COMPUTE_LIST: [&str; STRESS.len() + 1] = joined(STRESS, &["adaptive=0.008"]);
const SWEEP_COMPUTE_LIST: [&str; SWEEP.len() + ADAPTIVE_SWEEP.len()] = joined(SWEEP, ADAPTIVE_SWEEP);
/// raycast-compute's suite: the shared one, coarse steps in thin matter, and adaptive refinement.
pub const SUITE_COMPUTE: &[&str] = &SUITE_COMPUTE_LIST;
/// raycast-compute's stress sets: the shared ones and adaptive refinement.
pub const STRESS_COMPUTE: &[&str] = &STRESS_COMPUTE_LIST;
/// raycast-compute's sweep: the shared one and adaptive refinement's tolerances.
pub const SWEEP_COMPUTE: &[&str] = &SWEEP_COMPUTE_LIST;

/// What both variants register once.
pub const FAMILY: Family = Family {
    name: "raycast",
    check: crate::algo::settings::check::<Settings>,
    accuracy_bound,
    culling_option: None,
    placement: None,
    camera: |_, _| None,
};

/// The stress suite's bound on max |error| against the f64 reference (any
/// view, both integrators) where a case documents no limitation, at the
/// default step (0.5 voxel): measured on the "vol-baseline" case at 64x64,
/// 3.2e-4 (point) and 1.6e-4 (preint); 1e-3 is 3x the larger.
/// With `adaptive=TOL`, plus twice the tolerance ([`crate::algo::adaptive::bound`]);
/// with `coarse=A`, plus A (a coarse segment's optical depth is at most A,
/// so its opacity less; `tests/raycast.rs` measures 4.4e-3 at A = 0.1).
pub fn accuracy_bound(options: &Options, _perspective: bool) -> Option<f64> {
    let (adaptive, coarse) = Settings::from_options(options).map_or((0.0, 0.0), |s| (s.adaptive, s.coarse));
    Some(1e-3 + crate::algo::adaptive::bound(adaptive) + coarse)
}

/// Krüger & Westermann (Vis 2003): early ray termination and empty-space
/// skipping together speed ray casting up "by a factor of up to 3", on
/// their own volumes. The suite runs the option set without both on every
/// volume, so the report sets each measured speed-up beside the claim.
pub const fn kruger_westermann(method: &'static str) -> Published {
    Published {
        method,
        dataset: None,
        options: "ert=1,skip=off",
        figure: PublishedFigure::DefaultsFasterUpTo(3.0),
        source: "Krüger & Westermann, Vis 2003 (early termination and empty-space skipping)",
        note: "The saving is the fraction of each ray that is empty (skipped bricks) or behind opaque material \
               (terminated): large on volumes with much air and opaque structures, small where rays cross mostly \
               semi-transparent matter; the samples per ray in each run's `work` show it as work, not only as time.",
    }
}

impl Settings {
    /// Pre-integrated segments (`integrator=preint`).
    pub fn preint(&self) -> bool {
        self.integrator == RayIntegrator::Preint
    }
}

/// What the family's shaders are compiled for beside the settings: how
/// the volume is read ([`VolumeResources::shader_facts`]; set 0's layout
/// follows from it) and whether the compute march may reduce its counters
/// per subgroup (a device fact).
#[derive(Debug, Clone, Copy)]
pub struct ShaderFacts {
    /// The GLSL format the volume is read in with imageLoad (option
    /// `reads`); `None`: sampled.
    pub volume_load_format: Option<&'static str>,
    /// The loads are of four-sample quads (`reads=quads`).
    pub volume_quads: bool,
    /// The device has compute subgroup arithmetic.
    pub subgroup_counters: bool,
}

/// `raycast-compute`'s workgroup shape (pixels).
pub const COMPUTE_WORKGROUP: [u32; 2] = [8, 8];

/// Adaptive refinement's structural key (shaders/raycast/common.glsl):
/// runs through the bricks within this many bricks (Chebyshev) of one with
/// visible samples, and the upper limit of the distances it tells apart.
pub const KEY_NEAR: u32 = 8;

/// The brick distances the key tells apart in a frame whose bricks cover
/// at least `brick_pixels` pixels (None: no corner of the box is in front
/// of the eye): enough that a feature between two test rays of a block of
/// 8 ([`crate::algo::adaptive::BLOCK`] / 2 pixels apart) is nearer one of
/// them than the other by a brick, at most [`KEY_NEAR`].
pub fn key_close(brick_pixels: Option<f64>) -> u32 {
    let spacing = f64::from(crate::algo::adaptive::BLOCK / 2);
    match brick_pixels {
        Some(px) if px > 0.0 => ((spacing / px).ceil().min(f64::from(KEY_NEAR)) as u32).max(1),
        _ => KEY_NEAR,
    }
}

/// The box's triangles have outward right-handed normals: faces towards the
/// eye appear counter-clockwise on screen (Vulkan's y-down framebuffer).
const FRONT: Winding = Winding::CounterClockwise;

/// A pass of `raycast-fragment`: no vertex input, one RGBA32F target
/// overwritten, faces culled by `cull`.
fn fragment_pass_key(vertex: ShaderKey, fragment: ShaderKey, cull: Cull, sets: Vec<DescriptorSetDesc>) -> PipelineKey {
    PipelineKey::Graphics(GraphicsPipelineKey {
        vertex,
        geometry: None,
        fragment,
        state: GraphicsState {
            vertex_stride: 0,
            attributes: vec![],
            topology: Topology::TriangleList,
            primitive_restart: false,
            cull,
            front_face: FRONT,
            targets: vec![ColorTarget::rgba32f(Blend::None)],
            depth_test: false,
            depth_clamp: false,
        },
        push_constant_bytes: PUSH_BYTES,
        sets,
    })
}

/// The family's shader defines and pipeline keys, all made here from the
/// settings and the [`ShaderFacts`].
impl Settings {
    /// The build-time options as shader defines (the keys below add the
    /// volume's and the device's facts).
    fn defines(&self) -> Vec<(&'static str, &'static str)> {
        let mut d = Vec::new();
        if self.shade {
            d.push(("SHADE", "1"));
        }
        if self.preint() {
            d.push(("PREINT", "1"));
        }
        if self.skip {
            d.push(("SKIP", "1"));
        }
        if self.coarse > 0.0 {
            d.push(("COARSE_STRIDE", COARSE_STRIDE_DEFINE));
        }
        d
    }

    /// `coarse`: the attenuation (per world unit) above which a brick is
    /// dense: a coarse segment, [`COARSE_STRIDE`] steps of at most `step`
    /// voxels along the axis of largest spacing, keeps optical depth at
    /// most `coarse` below it. None when off.
    fn dense_above(&self, vol: &Volume) -> Option<f64> {
        let longest = vol.spacing().into_iter().fold(0.0, f64::max);
        (self.coarse > 0.0).then(|| self.coarse / (COARSE_STRIDE as f64 * self.step * longest))
    }

    /// The defines of every shader that includes the march
    /// (raycast/common.glsl): the build-time options and how the volume is
    /// read.
    fn march_defines(&self, facts: ShaderFacts) -> Vec<(&'static str, &'static str)> {
        let mut d = self.defines();
        if let Some(format) = facts.volume_load_format {
            d.push(("VOLUME_LOADS", "1"));
            d.push(("VOLUME_FORMAT", format));
            if facts.volume_quads {
                d.push(("VOLUME_QUADS", "1"));
            }
        }
        d
    }

    /// `raycast-compute`'s march into the target (set 1), with adaptive
    /// refinement's state at set 2 when given.
    pub fn compute_key(&self, facts: ShaderFacts, target: &DescriptorSetDesc, adaptive: Option<&DescriptorSetDesc>) -> PipelineKey {
        let wg = COMPUTE_WORKGROUP.map(|v| v.to_string());
        let near = format!("{KEY_NEAR}u");
        let mut d = self.march_defines(facts);
        // The march's counters reduced per subgroup (common.glsl) where the
        // device can.
        if facts.subgroup_counters {
            d.push(("SUBGROUP_COUNTERS", "1"));
        }
        d.push(("WG_X", &wg[0]));
        d.push(("WG_Y", &wg[1]));
        let mut sets = vec![set0_desc(facts.volume_load_format.is_some()), target.clone()];
        if let Some(state) = adaptive {
            d.push(("ADAPTIVE", "1"));
            d.push(("ADAPTIVE_NEAR", &near));
            sets.push(state.clone());
        }
        PipelineKey::Compute(ComputePipelineKey {
            shader: ShaderKey::new("raycast/march.comp", ShaderStage::Compute, &d),
            push_constant_bytes: if adaptive.is_some() { PUSH_BYTES_ADAPTIVE } else { PUSH_BYTES },
            sets,
        })
    }

    /// `raycast-fragment`'s box pass (front faces: `Cull::Back`, back faces:
    /// `Cull::Front`); its vertex stage includes raycast/common.glsl, so it
    /// takes set 0's layout and the march's defines.
    pub fn box_key(&self, facts: ShaderFacts, cull: Cull) -> PipelineKey {
        fragment_pass_key(
            ShaderKey::new("raycast/box.vert", ShaderStage::Vertex, &self.march_defines(facts)),
            ShaderKey::new("raycast/box.frag", ShaderStage::Fragment, &[]),
            cull,
            vec![set0_desc(facts.volume_load_format.is_some())],
        )
    }

    /// `raycast-fragment`'s full-screen march, the entry and exit points
    /// at set 1.
    pub fn fragment_march_key(&self, facts: ShaderFacts, points: &DescriptorSetDesc) -> PipelineKey {
        fragment_pass_key(
            ShaderKey::new("raycast/fullscreen.vert", ShaderStage::Vertex, &[]),
            ShaderKey::new("raycast/march.frag", ShaderStage::Fragment, &self.march_defines(facts)),
            Cull::None,
            vec![set0_desc(facts.volume_load_format.is_some()), points.clone()],
        )
    }
}

/// World length the pre-integration table is built for: the full step along
/// the axis of smallest spacing.
pub fn preint_length(vol: &Volume, step: f64) -> f64 {
    let s = vol.spacing();
    step * s[0].min(s[1]).min(s[2])
}

/// How a volume's samples become texels.
#[derive(Clone, Copy)]
enum Texels {
    /// The samples' own bytes (a normalized format of their width).
    Native,
    /// int16 shifted by 32768 into uint16 (for a volume holding -32768).
    ShiftedI16,
    /// f32 relative to the smallest sample.
    Float,
}

impl Texels {
    /// What is added to a sample to give the stored integer.
    fn bias(self) -> f64 {
        match self {
            Texels::ShiftedI16 => 32768.0,
            _ => 0.0,
        }
    }

    /// Bytes per texel.
    fn size(self, t: crate::volume::SampleType) -> usize {
        match self {
            Texels::Native => t.size(),
            Texels::ShiftedI16 => 2,
            Texels::Float => 4,
        }
    }

    /// Fills `dst` with the texels of samples `first..` (`lo`: the
    /// smallest sample, subtracted from floats); with `quads` (the volume's
    /// first two dimensions) each texel is four: its sample and the +x, +y
    /// and +x+y neighbours, clamped to the layer (a layer's texels need
    /// only its own samples).
    fn fill(self, samples: &Samples, lo: f64, first: usize, dst: &mut [u8], quads: Option<[usize; 2]>) {
        let Some([nx, ny]) = quads else { return self.fill_plain(samples, lo, first, dst) };
        let one = self.size(samples.sample_type());
        for (k, quad) in dst.chunks_exact_mut(4 * one).enumerate() {
            let t = first + k;
            let (i, j) = (t % nx, t / nx % ny);
            let dx = usize::from(i + 1 < nx);
            let dy = if j + 1 < ny { nx } else { 0 };
            for (c, n) in quad.chunks_exact_mut(one).zip([t, t + dx, t + dy, t + dx + dy]) {
                self.fill_plain(samples, lo, n, c);
            }
        }
    }

    fn fill_plain(self, samples: &Samples, lo: f64, first: usize, dst: &mut [u8]) {
        match (self, samples) {
            (Texels::ShiftedI16, Samples::I16(v)) => {
                for (t, &x) in dst.chunks_exact_mut(2).zip(&v[first..]) {
                    t.copy_from_slice(&((x as u16) ^ 0x8000).to_ne_bytes());
                }
            }
            (Texels::Native, _) => {
                let size = samples.sample_type().size();
                dst.copy_from_slice(&samples.as_bytes()[first * size..first * size + dst.len()]);
            }
            _ => {
                for (k, t) in dst.chunks_exact_mut(4).enumerate() {
                    let v = samples.get(first + k).unwrap_or(lo) as f32;
                    t.copy_from_slice(&((f64::from(v) - lo) as f32).to_ne_bytes());
                }
            }
        }
    }
}

/// Where the brick distances are computed ([`VolumeResources`]): in the
/// buffer the device reads on a CPU device (its memory is the process's:
/// no second copy), in host memory elsewhere, uploaded when done.
enum BrickMap {
    InPlace(Buffer, MapTexels),
    Host(Vec<u8>, MapTexels),
}

/// How the shader reads the brick map: bytes through a uniform texel
/// buffer, or with `reads=loads|quads` four bytes a word through a storage
/// one (brick i is bits 8·(i mod 4).. of word i / 4: the words are the
/// bytes in little-endian order, checked below), so that no lookup of the
/// march is an out-of-line call on lavapipe (module note). With `coarse`
/// a brick has two bytes (RG8, or two bricks a word).
#[derive(Clone, Copy)]
struct MapTexels {
    format: Format,
    usage: BufferUsage,
    /// Bytes a brick.
    entry: usize,
}

const _: () = assert!(cfg!(target_endian = "little"), "the brick map's words are read as little-endian bytes");

impl MapTexels {
    fn of(loads: bool, pairs: bool) -> Self {
        let entry = if pairs { 2 } else { 1 };
        match (loads, pairs) {
            (true, _) => MapTexels { format: Format::R32Uint, usage: BufferUsage::STORAGE_TEXEL, entry },
            (false, false) => MapTexels { format: Format::R8Uint, usage: BufferUsage::UNIFORM_TEXEL, entry },
            (false, true) => MapTexels { format: Format::Rg8Uint, usage: BufferUsage::UNIFORM_TEXEL, entry },
        }
    }
}

/// Test knob: `VOLBENCH_TEST_BRICK_MAP_HOST=1` takes the other devices' way
/// (host memory, then an upload) on a CPU device too, so that path is
/// tested on lavapipe.
pub const BRICK_MAP_HOST_VAR: &str = crate::switches::TEST_BRICK_MAP_HOST;

impl BrickMap {
    /// A map of `bricks` bricks.
    fn new(ctx: &Arc<Context>, bricks: usize, texels: MapTexels) -> Result<Self> {
        let padded = (bricks * texels.entry).next_multiple_of(texels.format.texel_bytes() as usize);
        Ok(if ctx.info.is_cpu() && !crate::switches::flag(BRICK_MAP_HOST_VAR).map_err(crate::vk::VkError::from)? {
            BrickMap::InPlace(Buffer::new(ctx, BufferDesc::upload("brick distances", padded as u64, texels.usage))?, texels)
        } else {
            BrickMap::Host(vec![0; padded], texels)
        })
    }

    fn mapped_for_write(&mut self) -> Result<&mut [u8]> {
        Ok(match self {
            BrickMap::InPlace(b, _) => b.mapped_for_write()?,
            BrickMap::Host(v, _) => v,
        })
    }

    /// The map as the shader's texel buffer, its bytes counted as uploaded.
    fn into_texels(self, ctx: &Arc<Context>, counter: &mut UploadCounter) -> Result<TexelBuffer> {
        Ok(match self {
            BrickMap::InPlace(b, t) => {
                counter.add_direct(UploadClass::Static, b.size());
                TexelBuffer::over(ctx, b, t.format)?
            }
            BrickMap::Host(v, t) => upload_static_texels(ctx, "brick distances", &v, t.format, t.usage, counter)?,
        })
    }
}

/// The device-side volume: texture, tables, brick flags, counters and the
/// static parameters (set 0 of both variants).
pub struct VolumeResources {
    pub set: DescriptorSet,
    _volume: crate::vk::Image,
    _tf: TfTable,
    _preint: crate::vk::Image,
    _params: Buffer,
    _bricks: TexelBuffer,
    counters: Buffer,
    _sampler: Sampler,
    pub texture_format: &'static str,
    /// The volume is read with imageLoad in this GLSL format (option
    /// `reads`), else sampled; `volume_quads`: four samples a texel.
    volume_load_format: Option<&'static str>,
    volume_quads: bool,
    pub brick_grid: [usize; 3],
    pub bricks_visible: usize,
    /// `coarse`: the bricks on which a coarse sample would be too thick.
    pub bricks_dense: Option<usize>,
    pub table_build_ms: f64,
    pub dims: [usize; 3],
    origin: DVec3,
    spacing: DVec3,
}

/// Set 0's layout (both variants).
/// Set 0's layout; the volume (binding 1) is a storage image when read
/// with loads (`VolumeResources::loads`).
pub fn set0_desc(loads: bool) -> DescriptorSetDesc {
    let st = Stages::FRAGMENT | Stages::COMPUTE | Stages::VERTEX;
    let volume = if loads { DescriptorKind::StorageImage } else { DescriptorKind::CombinedImageSampler };
    DescriptorSetDesc::default()
        .with(DescriptorKind::UniformBuffer, st)
        .with(volume, st)
        .with(if loads { DescriptorKind::StorageTexelBuffer } else { DescriptorKind::CombinedImageSampler }, st)
        .with(if loads { DescriptorKind::StorageTexelBuffer } else { DescriptorKind::UniformTexelBuffer }, st)
        .with(DescriptorKind::StorageBuffer, st)
        .with(DescriptorKind::CombinedImageSampler, st)
}

/// Where the volume's box lies in a frame's view ([`VolumeResources::on_screen`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BoxOnScreen {
    /// Every corner beyond one and the same clip plane: no ray meets the box.
    Hidden,
    /// The box lies inside the depth range (each corner at least
    /// [`DEPTH_MARGIN`] of it from the near and far planes), so a ray that
    /// meets it enters through a front face and leaves through a back face;
    /// the pixels it covers lie in `rect` (inclusive bounds).
    Whole { rect: [u32; 4] },
    /// The near or far plane cuts the box, or it reaches behind the eye.
    Cut,
}

/// How far (a part of the clip w) every corner must be from the near and
/// far planes for [`BoxOnScreen::Whole`]: far beyond the f32 rounding of
/// the device's clip coordinates.
pub const DEPTH_MARGIN: f64 = 1e-4;

/// [`BoxOnScreen`] of a box whose corners have the clip coordinates `clip`
/// (Vulkan's: -w <= x, y <= w, 0 <= z <= w) on an image of `size`.
pub fn box_on_screen(clip: &[glam::DVec4], size: [u32; 2]) -> BoxOnScreen {
    let outside = |f: &dyn Fn(&glam::DVec4) -> f64| clip.iter().all(|c| f(c) < 0.0);
    let planes: [&dyn Fn(&glam::DVec4) -> f64; 6] =
        [&|c| c.w + c.x, &|c| c.w - c.x, &|c| c.w + c.y, &|c| c.w - c.y, &|c| c.z, &|c| c.w - c.z];
    if planes.iter().any(|f| outside(*f)) {
        return BoxOnScreen::Hidden;
    }
    let inside_depth = |c: &glam::DVec4| c.w > 0.0 && c.z >= DEPTH_MARGIN * c.w && c.w - c.z >= DEPTH_MARGIN * c.w && c.is_finite();
    if !clip.iter().all(inside_depth) {
        return BoxOnScreen::Cut;
    }
    // NDC to pixels as the viewport maps them (x + 0.5 the centre of pixel x).
    let pixels = clip.iter().map(|c| [(c.x / c.w * 0.5 + 0.5) * f64::from(size[0]), (c.y / c.w * 0.5 + 0.5) * f64::from(size[1])]);
    BoxOnScreen::Whole { rect: super::screen::pixel_bounds(pixels, 1.0, size) }
}

/// Counter words read back after every frame.
const COUNTER_WORDS: usize = 6;

fn f32_bytes(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_ne_bytes()).collect()
}

/// The samples the texture is made from (`given`, else the volume's),
/// checked against the device's 3D image limit and the volume's grid.
fn checked_samples<'a>(ctx: &Context, vol: &'a Volume, given: Option<&'a Samples>) -> Result<&'a Samples> {
    let dims = vol.dims();
    let max3 = ctx.info.max_image_dimension_3d as usize;
    if dims.iter().any(|&d| d > max3) {
        bail!("volume '{}': {:?} exceeds the device's 3D image limit {max3}", vol.name, dims);
    }
    if dims.iter().any(|&d| d < 2) {
        bail!("volume '{}': {:?} has no extent along some axis (at least 2 samples per axis are needed)", vol.name, dims);
    }
    let samples = given.unwrap_or(vol.samples());
    if samples.len() != vol.len() {
        bail!("volume '{}': {} samples for its {:?} grid (its samples were taken)", vol.name, samples.len(), dims);
    }
    Ok(samples)
}

/// The ray casters' static parameters (`shaders/raycast/params.glsl`,
/// std140, uploaded once; `tests/shader_interfaces.rs` checks the two agree).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Params {
    /// dims - 1: the box in voxel coordinates.
    pub box_max: Vec3,
    /// Brick edge in voxels (option `brick`).
    pub brick: f32,
    /// 1 / dims.
    pub inv_dims: Vec3,
    /// Entries of the table: the 1D transfer function's, or the PREINT
    /// table's side.
    pub table_entries: f32,
    /// World units per voxel.
    pub spacing: Vec3,
    /// Largest step in voxels (option `step`).
    pub step: f32,
    /// Normalised texel v -> table coordinate t = tf_scale * (v - tf_offset).
    pub tf_scale: f32,
    pub tf_offset: f32,
    /// Early-termination threshold (option `ert`).
    pub ert: f32,
    /// World length the PREINT table is built for ([`preint_length`]).
    pub preint_length: f32,
    /// Bricks along each axis.
    pub brick_grid: Vec3,
    /// Blinn-Phong (`shade=on`, module note).
    pub ambient: f32,
    pub diffuse: f32,
    pub specular: f32,
    pub shininess: f32,
}

/// The ray casters' push constants (`shaders/raycast/frame.glsl`;
/// `tests/shader_interfaces.rs` checks the two agree).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Frame {
    /// Box pass: voxel -> clip; march: NDC -> voxel (homogeneous).
    pub m: [[f32; 4]; 4],
    /// The compute march's first workgroup (x, y), its rows of workgroups
    /// and the device's runs (`crate::algo::screen::interleaved_rows`).
    pub first_group: [u32; 2],
    pub rows: u32,
    pub runs: u32,
    /// Unit direction towards the light, world axes.
    pub light: Vec3,
}

/// [`Frame`] with adaptive refinement (raycast-compute, ADAPTIVE).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct AdaptiveFrame {
    pub frame: Frame,
    /// The brick distances the structural key tells apart ([`key_close`]).
    pub close: u32,
    /// The frame's rectangle, inclusive pixel bounds.
    pub rect: [u32; 4],
    /// The cast pass's step (8, 4, 2, 1; `shaders/common/adaptive.glsl`).
    pub cast_step: u32,
}

/// The push-constant ranges of the pipelines: without and with ADAPTIVE.
pub const PUSH_BYTES: u32 = std::mem::size_of::<Frame>() as u32;
pub const PUSH_BYTES_ADAPTIVE: u32 = std::mem::size_of::<AdaptiveFrame>() as u32;

/// How the volume's samples are stored on the device and read by the march
/// ([`VolumeResources::new`]'s first step).
struct TextureChoice {
    format: Format,
    /// Recorded in `details.texture_format`.
    name: &'static str,
    /// A texel's value v is the sample (v - offset) * scale... as the
    /// params' `tf_scale` and `tf_offset` take it: t = tscale * (v - offset).
    scale: f64,
    offset: f64,
    texels: Texels,
    /// Bytes per texel.
    texel_bytes: usize,
    /// Read with imageLoad in this GLSL format (option `reads`), else sampled.
    load_format: Option<&'static str>,
    /// Each texel four samples (`reads=quads`; `format` the four-channel one).
    quads: bool,
    /// The samples' range (hi > lo).
    lo: f64,
    hi: f64,
}

impl TextureChoice {
    /// Native formats where the device filters them; texel value v maps
    /// back to the sample as value = v * scale - bias. int16 with -32768
    /// (which snorm maps to -1 like -32767) is stored shifted by 32768 as
    /// unorm: linear filtering commutes with the shift, so the filtered
    /// values are the samples' (a float texture was twice the bytes).
    fn of(ctx: &Context, vol: &Volume, samples: &Samples, s: &Settings) -> Result<Self> {
        let native: Option<(Format, &'static str, f64, Texels)> = match samples {
            Samples::U8(_) => Some((Format::R8Unorm, "r8-unorm", 255.0, Texels::Native)),
            Samples::U16(_) => Some((Format::R16Unorm, "r16-unorm", 65535.0, Texels::Native)),
            Samples::I16(v) if !v.contains(&i16::MIN) => Some((Format::R16Snorm, "r16-snorm", 32767.0, Texels::Native)),
            Samples::I16(_) => Some((Format::R16Unorm, "r16-unorm-shifted", 65535.0, Texels::ShiftedI16)),
            Samples::F32(_) => None,
        };
        let (lo, mut hi) = vol.range();
        if !(hi > lo) {
            hi = lo + 1.0;
        }
        // Float samples are stored relative to the smallest (subtracted in
        // f64): filtering then works on the range's own bits, not on a large
        // offset's (1e6 + [0, 1] would be filtered in steps of 1/16). They
        // are converted slab by slab into the staging buffer, never held
        // whole beside the volume.
        let (format, name, scale, offset, texels) = match native {
            Some((f, n, s, t)) if ctx.can_sample(f, Filter::Linear) => (f, n, s, (lo + t.bias()) / s, t),
            _ => (Format::R32Float, "r32-sfloat", 1.0, 0.0, Texels::Float),
        };
        let loadable = ctx.can_load(format);
        let quad = quad_format(format).filter(|&q| ctx.can_load(q));
        let texel_bytes = texels.size(samples.sample_type());
        let cannot = |reads: &str| {
            anyhow::anyhow!("reads={reads}: device '{}' cannot read {name} 3D images with imageLoad (use reads=texture)", ctx.info.name)
        };
        let (loads, quads) = match s.reads {
            VolumeReads::Texture => (false, false),
            VolumeReads::Loads if !loadable => return Err(cannot("loads")),
            VolumeReads::Loads => (true, false),
            VolumeReads::Quads if quad.is_none() => return Err(cannot("quads")),
            VolumeReads::Quads => (true, true),
            VolumeReads::Auto => (loadable && ctx.info.is_cpu(), false),
        };
        if !loads && !ctx.can_sample(format, Filter::Linear) {
            bail!("device '{}' cannot filter {name} 3D textures linearly", ctx.info.name);
        }
        let (format, texel_bytes) = match quad {
            Some(q) if quads => (q, 4 * texel_bytes),
            _ => (format, texel_bytes),
        };
        let load_format = if loads { format.glsl_image_format().map(|(f, _)| f) } else { None };
        Ok(TextureChoice { format, name, scale, offset, texels, texel_bytes, load_format, quads, lo, hi })
    }
}

/// The four-channel format of a single-channel volume format (`reads=quads`).
fn quad_format(f: Format) -> Option<Format> {
    Some(match f {
        Format::R8Unorm => Format::Rgba8Unorm,
        Format::R16Unorm => Format::Rgba16Unorm,
        Format::R16Snorm => Format::Rgba16Snorm,
        Format::R32Float => Format::Rgba32Float,
        _ => return None,
    })
}

/// The transfer function's 1D table: a texture sampled with its linear
/// filter, or a storage texel buffer blended in the shader
/// (`reads=loads|quads`: on lavapipe a texture lookup is an out-of-line call).
enum TfTable {
    Image(crate::vk::Image),
    Texels(TexelBuffer),
}

/// The volume's texture and its brick distances, built together
/// ([`upload_volume_and_bricks`]).
struct BrickedVolume {
    volume: crate::vk::Image,
    bricks: TexelBuffer,
    grid: [usize; 3],
    visible: usize,
    /// `coarse`: the dense bricks.
    dense: Option<usize>,
    /// Time spent flagging bricks and computing distances (the upload's not included).
    ms: f64,
}

/// The volume's texture and brick distances (module note): 0 on a flagged
/// brick, else the Chebyshev distance to the nearest one; for `preint` the
/// flags are dilated by the bricks half a step may reach into.
///
/// A uniform texel buffer (a distance is one texel fetch; as a storage
/// buffer, a per-ray index made llvmpipe loop over the SIMD lanes). On a
/// CPU device the distances are computed in the memory the device reads,
/// one byte a brick and no other copy (at `brick=1` the map is as large as
/// an 8-bit volume); elsewhere in host memory and uploaded to device-local
/// memory (host-visible memory there is uncached for the CPU's reads and
/// crosses the bus for the shader's).
///
/// Memory (docs/bad-input.md, "Memory"). Samples of our own (`given`): the
/// texture is filled from the last slab to the first, each brick layer is
/// flagged as soon as its sample layers are filled, and the samples are
/// given back down to what is yet to be filled or flagged. Shared samples
/// (they stay for the next method): the flags first, then the texture. The
/// distances follow in the map.
fn upload_volume_and_bricks(
    ctx: &Arc<Context>,
    vol: &Volume,
    given: Option<Samples>,
    tf: &TransferFunction,
    s: &Settings,
    choice: &TextureChoice,
    counter: &mut UploadCounter,
) -> Result<BrickedVolume> {
    let dims = vol.dims();
    let grid = bricks::grid_of(dims, s.brick);
    let dilation = if s.preint() { (s.step / (2.0 * s.brick as f64)).ceil().max(1.0) as u8 } else { 0 };
    let mut bricks_ms = 0.0;
    let layer_bricks = grid[0] * grid[1];
    let map_bytes = layer_bricks * grid[2];
    let dense_above = s.dense_above(vol);
    let new_map = || BrickMap::new(ctx, map_bytes, MapTexels::of(choice.load_format.is_some(), dense_above.is_some()));
    // `coarse`: one bit a brick, set on dense ones, while the map fills.
    let mut dense = bit_vec::BitVec::from_elem(if dense_above.is_some() { map_bytes } else { 0 }, false);
    let mut desc = TextureDesc::d3(&format!("volume '{}'", vol.name), dims.map(|d| d as u32), choice.format);
    if choice.load_format.is_some() {
        desc = desc.for_loads();
    }
    // Texels from sample offset / texel size on.
    let texels = choice.texels;
    let lo = choice.lo;
    let texel = choice.texel_bytes;
    let quads = choice.quads.then_some([dims[0], dims[1]]);
    let fill = |samples: &Samples, offset: usize, dst: &mut [u8]| texels.fill(samples, lo, offset / texel, dst, quads);
    let layer = dims[0] * dims[1];
    let (mut map, volume) = match given {
        Some(mut own) => {
            // One bit a brick while the texture fills (samples and
            // texture are then two copies at the first slab); the map
            // once the samples are gone.
            let mut flagger = bricks::LayerFlags::new(dims, tf, s.brick);
            let mut flagged = bit_vec::BitVec::from_elem(map_bytes, false);
            // Brick layers next.. are flagged, last first.
            let mut next = grid[2];
            let volume = upload_texture_with(ctx, &desc, counter, &mut |offset, dst| {
                fill(&own, offset, dst);
                let first = offset / texel / layer;
                let t = Instant::now();
                while next > 0 && (next - 1) * s.brick >= first {
                    next -= 1;
                    for (b, f) in flagger.flags(next, &own).into_iter().enumerate() {
                        flagged.set(next * layer_bricks + b, f);
                    }
                    mark_dense(&mut dense, &flagger, dense_above, next * layer_bricks);
                }
                bricks_ms += t.elapsed().as_secs_f64() * 1e3;
                let keep = if next == 0 { first } else { first.max(flagger.sample_layers(next - 1).end() + 1) };
                own.truncate(keep * layer);
            });
            drop(own);
            let volume = volume.with_context(|| format!("uploading volume '{}'", vol.name))?;
            let mut map = new_map()?;
            bricks::mark(flagged.iter(), &mut map.mapped_for_write()?[..map_bytes]);
            (map, volume)
        }
        None => {
            // The flags first, straight into the map.
            let t = Instant::now();
            let mut map = new_map()?;
            let mut flagger = bricks::LayerFlags::new(dims, tf, s.brick);
            for (bz, cells) in map.mapped_for_write()?[..map_bytes].chunks_exact_mut(layer_bricks).enumerate() {
                bricks::mark(flagger.flags(bz, vol.samples()), cells);
                mark_dense(&mut dense, &flagger, dense_above, bz * layer_bricks);
            }
            bricks_ms += t.elapsed().as_secs_f64() * 1e3;
            let volume = upload_texture_with(ctx, &desc, counter, &mut |offset, dst| fill(vol.samples(), offset, dst))
                .with_context(|| format!("uploading volume '{}'", vol.name))?;
            (map, volume)
        }
    };
    let t = Instant::now();
    let (visible, dense_bricks) = map_distances(&mut map, grid, dilation, dense_above.map(|_| &dense))?;
    bricks_ms += t.elapsed().as_secs_f64() * 1e3;
    let bricks = map.into_texels(ctx, counter)?;
    Ok(BrickedVolume { volume, bricks, grid, visible, dense: dense_bricks, ms: bricks_ms })
}

/// `coarse`: sets the dense bricks of the layer [`bricks::LayerFlags`]
/// flagged last, from brick `first` of the map on (none when off).
fn mark_dense(dense: &mut bit_vec::BitVec, flagger: &bricks::LayerFlags, dense_above: Option<f64>, first: usize) {
    if let Some(tau) = dense_above {
        for (b, f) in flagger.dense(tau).into_iter().enumerate() {
            dense.set(first + b, f);
        }
    }
}

/// Turns the marked map of `grid` into distances (flags dilated by
/// `dilation` bricks), and with `dense` (`coarse`: one bit a brick) gives
/// each brick its second byte, the distance to the nearest dense one (one
/// more byte a brick while the pairs are made). The visible bricks, and
/// the dense ones.
fn map_distances(map: &mut BrickMap, grid: [usize; 3], dilation: u8, dense: Option<&bit_vec::BitVec>) -> Result<(usize, Option<usize>)> {
    let n = grid[0] * grid[1] * grid[2];
    let cells = &mut map.mapped_for_write()?[..n];
    bricks::chebyshev_in_place(cells, grid);
    for d in cells.iter_mut() {
        *d = d.saturating_sub(dilation);
    }
    let visible = cells.iter().filter(|&&d| d == 0).count();
    let Some(dense) = dense else { return Ok((visible, None)) };
    let mut second = vec![0u8; n];
    bricks::mark(dense.iter(), &mut second);
    bricks::chebyshev_in_place(&mut second, grid);
    let dense_bricks = second.iter().filter(|&&d| d == 0).count();
    bricks::interleave_pairs(map.mapped_for_write()?, &second);
    Ok((visible, Some(dense_bricks)))
}

/// The transfer function's 1D table over [lo, hi] and the pre-integration
/// table over (front, back) in [lo, hi]^2, texel centres at the ends:
/// premultiplied colour and optical depth of a segment of
/// [`preint_length`] world units, exact (`algo::segment`); 2x2 (unread)
/// without `preint`. Its side is the returned count.
fn upload_tables(
    ctx: &Arc<Context>,
    vol: &Volume,
    tf: &TransferFunction,
    s: &Settings,
    (lo, hi): (f64, f64),
    loads: bool,
    counter: &mut UploadCounter,
) -> Result<(TfTable, crate::vk::Image, usize)> {
    let table: Vec<f32> = tf.table(TABLE_SIZE, lo, hi).concat();
    let tf_img = if loads {
        TfTable::Texels(upload_static_texels(ctx, "transfer function", &f32_bytes(&table), Format::Rgba32Float, BufferUsage::STORAGE_TEXEL, counter)?)
    } else {
        TfTable::Image(upload_texture(ctx, &TextureDesc::d1("transfer function", TABLE_SIZE as u32, Format::Rgba32Float), &f32_bytes(&table), counter)?)
    };
    let d0 = preint_length(vol, s.step);
    let n = if s.preint() { PREINT_SIZE } else { 2 };
    let mut pre = Vec::with_capacity(n * n * 4);
    for b in 0..n {
        for f in 0..n {
            let sf = lo + (hi - lo) * f as f64 / (n - 1) as f64;
            let sb = lo + (hi - lo) * b as f64 / (n - 1) as f64;
            let seg = integrate_segment(tf, sf, sb, d0);
            let depth = seg.optical_depth.min(1e30);
            pre.extend([seg.color[0] as f32, seg.color[1] as f32, seg.color[2] as f32, depth as f32]);
        }
    }
    let preint = upload_texture(ctx, &TextureDesc::d2("pre-integration table", n as u32, n as u32, Format::Rgba32Float), &f32_bytes(&pre), counter)?;
    Ok((tf_img, preint, n))
}

impl Params {
    /// The parameters of `vol` under `s`, its samples stored as `choice`
    /// says, its bricks in `grid`, its PREINT table `preint_side` a side.
    fn new(vol: &Volume, s: &Settings, choice: &TextureChoice, grid: [usize; 3], preint_side: usize) -> Self {
        let dims = vol.dims();
        let f32s = |v: [usize; 3]| Vec3::new(v[0] as f32, v[1] as f32, v[2] as f32);
        // t = (v - offset) * scale / (hi - lo), offset lo / scale for the
        // native formats (0 for floats, stored relative to lo): the
        // subtraction first, so a small range far from zero keeps its bits.
        let tscale = choice.scale / (choice.hi - choice.lo);
        Params {
            box_max: f32s(dims.map(|d| d - 1)),
            brick: s.brick as f32,
            inv_dims: Vec3::new(1.0 / dims[0] as f32, 1.0 / dims[1] as f32, 1.0 / dims[2] as f32),
            table_entries: if s.preint() { preint_side as f32 } else { TABLE_SIZE as f32 },
            spacing: DVec3::from(vol.spacing()).as_vec3(),
            step: s.step as f32,
            tf_scale: tscale as f32,
            tf_offset: choice.offset as f32,
            ert: s.ert as f32,
            preint_length: preint_length(vol, s.step) as f32,
            brick_grid: f32s(grid),
            ambient: 0.3,
            diffuse: 0.7,
            specular: 0.25,
            shininess: 30.0,
        }
    }
}

impl VolumeResources {
    /// `given`: the volume's samples taken from it (`Volume::take_samples`)
    /// when nothing reads them after this set-up: they are given back to
    /// the system slab by slab as the texture receives them. `None`: they
    /// are read from `vol`.
    pub fn new(
        ctx: &Arc<Context>,
        vol: &Volume,
        given: Option<Samples>,
        tf: &TransferFunction,
        s: &Settings,
        counter: &mut UploadCounter,
    ) -> Result<Self> {
        let choice = {
            let samples = checked_samples(ctx, vol, given.as_ref())?;
            TextureChoice::of(ctx, vol, samples, s)?
        };
        let bricked = upload_volume_and_bricks(ctx, vol, given, tf, s, &choice, counter)?;
        let t0 = Instant::now();
        let (tf_img, preint, preint_side) = upload_tables(ctx, vol, tf, s, (choice.lo, choice.hi), choice.load_format.is_some(), counter)?;
        let table_build_ms = bricked.ms + t0.elapsed().as_secs_f64() * 1e3;
        let params = Params::new(vol, s, &choice, bricked.grid, preint_side);
        let mut params_buf = Buffer::new(ctx, BufferDesc::upload("raycast parameters", std::mem::size_of::<Params>() as u64, BufferUsage::UNIFORM))?;
        params_buf.write(0, bytemuck::bytes_of(&params), counter, UploadClass::Static)?;
        let counters = Buffer::new(ctx, BufferDesc::counters("raycast counters", COUNTER_WORDS))?;
        let sampler = Sampler::linear_clamp(ctx, "raycast linear")?;
        let loads = choice.load_format.is_some();
        let volume = &bricked.volume;
        let set = DescriptorSet::new(
            ctx,
            "raycast volume",
            &set0_desc(loads),
            &[
                DescriptorResource::UniformBuffer(&params_buf),
                if loads { DescriptorResource::StorageImage(volume) } else { DescriptorResource::CombinedImageSampler(volume, &sampler) },
                match &tf_img {
                    TfTable::Texels(t) => DescriptorResource::StorageTexelBuffer(t),
                    TfTable::Image(i) => DescriptorResource::CombinedImageSampler(i, &sampler),
                },
                if loads { DescriptorResource::StorageTexelBuffer(&bricked.bricks) } else { DescriptorResource::UniformTexelBuffer(&bricked.bricks) },
                DescriptorResource::StorageBuffer(&counters),
                DescriptorResource::CombinedImageSampler(&preint, &sampler),
            ],
        )?;
        Ok(VolumeResources {
            set,
            _volume: bricked.volume,
            _tf: tf_img,
            _preint: preint,
            _params: params_buf,
            _bricks: bricked.bricks,
            counters,
            _sampler: sampler,
            texture_format: choice.name,
            volume_load_format: choice.load_format,
            volume_quads: choice.quads,
            brick_grid: bricked.grid,
            bricks_visible: bricked.visible,
            bricks_dense: bricked.dense,
            table_build_ms,
            dims: vol.dims(),
            origin: vol.origin().into(),
            spacing: vol.spacing().into(),
        })
    }

    /// voxel -> world.
    fn world_from_voxel(&self) -> DMat4 {
        DMat4::from_translation(self.origin) * DMat4::from_scale(self.spacing)
    }

    /// Where the box falls in `view` (its corners through the same f64
    /// voxel -> clip matrix the box pass draws with).
    pub fn on_screen(&self, view: &View) -> BoxOnScreen {
        let m = view.camera.view_proj(view.width, view.height) * self.world_from_voxel();
        let clip: Vec<glam::DVec4> = self.box_corners().map(|u| m * u.extend(1.0)).collect();
        box_on_screen(&clip, [view.width, view.height])
    }

    /// The box's eight corners in voxel coordinates.
    fn box_corners(&self) -> impl Iterator<Item = DVec3> {
        let hi = DVec3::new((self.dims[0] - 1) as f64, (self.dims[1] - 1) as f64, (self.dims[2] - 1) as f64);
        (0..8).map(move |c| DVec3::new(if c & 1 != 0 { hi.x } else { 0.0 }, if c & 2 != 0 { hi.y } else { 0.0 }, if c & 4 != 0 { hi.z } else { 0.0 }))
    }

    /// The fewest pixels a brick's edge (`brick` voxels of the smallest
    /// spacing) covers at any corner of the box in front of the eye under
    /// `view`, across the view direction; None when no corner is.
    pub fn brick_pixels(&self, view: &View, brick: f64) -> Option<f64> {
        let vp = view.camera.view_proj(view.width, view.height);
        let w = self.world_from_voxel();
        let right = view.camera.forward().cross(DVec3::from(view.camera.up)).normalize();
        let edge = right * (brick * self.spacing.min_element());
        let half = glam::DVec2::new(f64::from(view.width), f64::from(view.height)) * 0.5;
        self.box_corners()
            .filter_map(|u| {
                let p = w.transform_point3(u);
                let (a, b) = (vp * p.extend(1.0), vp * (p + edge).extend(1.0));
                (a.w > 0.0 && b.w > 0.0).then(|| ((a.truncate().truncate() / a.w - b.truncate().truncate() / b.w) * half).length())
            })
            .reduce(f64::min)
    }

    /// Push constants for the view: `m` (voxel -> clip, or NDC -> voxel),
    /// the compute pass's tiles (`first_group`, `rows`: its first workgroup
    /// and rows of workgroups; `runs`: the device's runs,
    /// `crate::algo::screen::interleaved_rows`) and the light direction
    /// (world axes).
    pub fn frame(&self, view: &View, ndc_to_voxel: bool, first_group: [u32; 2], rows: u32, runs: u32) -> Frame {
        let vp = view.camera.view_proj(view.width, view.height);
        let w = self.world_from_voxel();
        let m = if ndc_to_voxel { w.inverse() * vp.inverse() } else { vp * w };
        // A headlight raised a little above the view direction.
        let fwd = view.camera.forward();
        let light = (-fwd + DVec3::from(view.camera.up) * 0.5).normalize();
        Frame { m: m.to_cols_array_2d().map(|c| c.map(|x| x as f32)), first_group, rows, runs, light: light.as_vec3() }
    }

    /// Clear the counters before the frame's passes.
    pub fn record_clear(&self, rec: &CommandRecorder) {
        rec.fill_buffer(&self.counters, 0);
        rec.transfer_to_storage(Stages::COMPUTE | Stages::FRAGMENT);
    }

    /// Make the counters' writes visible to the host after the frame.
    pub fn record_counters_to_host(&self, rec: &CommandRecorder) {
        rec.storage_to_host(Stages::COMPUTE | Stages::FRAGMENT);
    }

    /// The last frame's counters: (total samples, max per ray, bricks skipped, rays, leaps, of them leaps over the ray's empty ends).
    pub fn counters(&self) -> [u64; COUNTER_WORDS] {
        self.counters.read_counters()
    }

    pub fn work(&self, pixels: u64) -> Work {
        let [total, max, skipped, rays, leaps, end_leaps] = self.counters();
        Work::default()
            .with("pixels", pixels)
            .with("rays", rays)
            .with("samples", total)
            .with("max_samples_per_ray", max)
            .with("bricks_skipped", skipped)
            .with("leaps", leaps)
            .with("leaps_at_ends", end_leaps)
    }

    /// Whether the volume is read with imageLoad (set 0's binding 1 a storage image).
    pub fn loads(&self) -> bool {
        self.volume_load_format.is_some()
    }

    /// What the family's shaders are compiled for on this device, for
    /// this volume ([`Settings::compute_key`] and the others).
    pub fn shader_facts(&self, ctx: &Context) -> ShaderFacts {
        ShaderFacts {
            volume_load_format: self.volume_load_format,
            volume_quads: self.volume_quads,
            subgroup_counters: ctx.info.compute_subgroup_arithmetic,
        }
    }

    pub fn details(&self, s: &Settings, variant: serde_json::Value) -> serde_json::Value {
        let [total, max, skipped, rays, leaps, end_leaps] = self.counters();
        json!({
            "family": "raycast",
            "variant": variant,
            "texture_format": self.texture_format,
            "volume_reads": match (self.loads(), self.volume_quads) {
                (true, true) => "quads",
                (true, false) => "loads",
                _ => "texture",
            },
            "dims": self.dims,
            "step_voxels": s.step,
            "ert": s.ert,
            "table_size": if s.preint() { PREINT_SIZE } else { TABLE_SIZE },
            "brick": s.brick,
            "brick_grid": self.brick_grid,
            "bricks_visible": self.bricks_visible,
            "coarse": if s.coarse > 0.0 {
                json!({ "optical_depth": s.coarse, "stride": COARSE_STRIDE, "bricks_dense": self.bricks_dense })
            } else {
                serde_json::Value::Null
            },
            "samples_per_ray_mean": if rays > 0 { total as f64 / rays as f64 } else { 0.0 },
            "samples_per_ray_max": max,
            "bricks_skipped": skipped,
            "leaps": leaps,
            "leaps_at_ends": end_leaps,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec4;

    fn corners(lo: [f64; 3], hi: [f64; 3]) -> Vec<DVec4> {
        (0..8)
            .map(|c| {
                let pick = |k: usize| if c & (1 << k) != 0 { hi[k] } else { lo[k] };
                DVec4::new(pick(0), pick(1), pick(2), 1.0)
            })
            .collect()
    }

    #[test]
    fn the_box_is_placed_by_its_corners_clip_coordinates() {
        let size = [100, 80];
        // Clip coordinates with w = 1: inside the depth range, centred; x in
        // [25, 75] px, y in [30, 50] px, padded by one pixel.
        let inside = corners([-0.5, -0.25, 0.2], [0.5, 0.25, 0.8]);
        assert_eq!(box_on_screen(&inside, size), BoxOnScreen::Whole { rect: [24, 29, 76, 51] });
        // Past the right edge: clamped.
        assert_eq!(box_on_screen(&corners([0.5, -0.25, 0.2], [1.5, 0.25, 0.8]), size), BoxOnScreen::Whole { rect: [74, 29, 99, 51] });
        // Wholly beyond one plane: hidden.
        assert_eq!(box_on_screen(&corners([1.1, -0.25, 0.2], [2.0, 0.25, 0.8]), size), BoxOnScreen::Hidden);
        assert_eq!(box_on_screen(&corners([-0.5, -0.25, -0.8], [0.5, 0.25, -0.1]), size), BoxOnScreen::Hidden);
        assert_eq!(box_on_screen(&corners([-0.5, -0.25, 1.1], [0.5, 0.25, 1.5]), size), BoxOnScreen::Hidden);
        // The near or the far plane through it, or a corner within the
        // margin of one: cut.
        assert_eq!(box_on_screen(&corners([-0.5, -0.25, -0.1], [0.5, 0.25, 0.8]), size), BoxOnScreen::Cut);
        assert_eq!(box_on_screen(&corners([-0.5, -0.25, 0.2], [0.5, 0.25, 1.2]), size), BoxOnScreen::Cut);
        assert_eq!(box_on_screen(&corners([-0.5, -0.25, 0.5 * DEPTH_MARGIN], [0.5, 0.25, 0.8]), size), BoxOnScreen::Cut);
        // A corner behind the eye (w < 0): cut, never whole.
        let mut behind = inside.clone();
        behind[0] = DVec4::new(0.1, 0.1, -0.5, -1.0);
        assert_eq!(box_on_screen(&behind, size), BoxOnScreen::Cut);
    }
}
