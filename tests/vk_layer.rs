//! The Vulkan layer's building blocks for the next method families, each
//! exercised on lavapipe with the validation layer on (any message fails):
//! compute pipelines and dispatches beyond the per-dimension group limit,
//! 1D/2D/3D sampled images against CPU interpolation, texel buffers, general
//! descriptor sets, several colour attachments, compute writing the render
//! target, geometry shaders with their statistics, the pipeline cache and its
//! stable ids, bounded waits (no hang on an unsubmitted recorder) and strict
//! environment switches. Assertions are on values and counts, never timings.

use std::sync::mpsc;
use std::sync::{Arc, Mutex, OnceLock};
use std::time::Duration;

use volbench::vk::{BufferUsage, Cull, Filter, Format, Stages, Topology, Winding};
use volbench::vk::{
    compile_glsl, fold_groups, parse_env_flag, parse_fence_timeout, upload_texture, Blend, Buffer, BufferDesc,
    ColorAttachment, ColorTarget, CommandRecorder, ComputePipelineDesc, ComputePipelineKey, Context, ContextDesc,
    DescriptorKind, DescriptorResource, DescriptorSet, DescriptorSetDesc, DeviceFeatures, FrameQueries,
    GraphicsPipelineDesc, GraphicsPipelineKey, GraphicsState, Image, ImageUse, MemoryKind, Pipeline, PipelineCache,
    PipelineKey, Sampler, ShaderKey, ShaderModule, ShaderStage, TexelBuffer, TextureDesc, UploadClass, UploadCounter,
    VkError, DEFAULT_FENCE_TIMEOUT,
};

/// One validated context for the whole test binary; tests are serialised
/// because lavapipe already uses every core.
fn context() -> std::sync::MutexGuard<'static, Arc<Context>> {
    static CTX: OnceLock<Mutex<Arc<Context>>> = OnceLock::new();
    CTX.get_or_init(|| {
        let ctx = Context::new(&ContextDesc { device: None, validation: true }).expect("a Vulkan device (run scripts/setup.sh)");
        Mutex::new(ctx)
    })
    .lock()
    .unwrap_or_else(|p| p.into_inner())
}

fn assert_no_validation(ctx: &Context) {
    let msgs = ctx.validation_messages();
    assert!(msgs.is_empty(), "validation messages: {msgs:#?}");
}

const COUNT_GROUPS_COMP: &str = r#"#version 450
#include "common/dispatch.glsl"
layout(local_size_x = 32) in;
layout(push_constant) uniform P { uint count; uint groups; } p;
layout(set = 0, binding = 0) buffer Hits { uint hits[]; };
layout(set = 0, binding = 1) buffer Groups { uint groups_run; };
void main() {
    if (linear_workgroup_id() >= p.groups) return;   // excess groups of the folded grid
    if (gl_LocalInvocationIndex == 0u) atomicAdd(groups_run, 1u);
    uint i = linear_invocation_id();
    if (i < p.count) atomicAdd(hits[i], 1u);
}
"#;

const SAMPLE_3D_COMP: &str = r#"#version 450
layout(local_size_x = 16) in;
layout(set = 0, binding = 0) uniform Params { uint count; } params;
layout(set = 0, binding = 1) uniform sampler3D volume;
layout(set = 0, binding = 2) readonly buffer Coords { vec4 coords[]; };
layout(set = 0, binding = 3) writeonly buffer Out { float result[]; };
void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= params.count) return;
    result[i] = textureLod(volume, coords[i].xyz, 0.0).r;
}
"#;

const FETCH_3D_INT_COMP: &str = r#"#version 450
layout(local_size_x = 16) in;
layout(push_constant) uniform P { uint count; ivec3 size; } p;
layout(set = 0, binding = 0) uniform isampler3D volume;
layout(set = 0, binding = 1) writeonly buffer Out { int result[]; };
void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= p.count) return;
    ivec3 c = ivec3(int(i) % p.size.x, (int(i) / p.size.x) % p.size.y, int(i) / (p.size.x * p.size.y));
    result[i] = texelFetch(volume, c, 0).r;
}
"#;

const SAMPLE_TABLES_COMP: &str = r#"#version 450
layout(local_size_x = 16) in;
layout(push_constant) uniform P { uint count; } p;
layout(set = 0, binding = 0) uniform sampler1D tf;
layout(set = 0, binding = 1) uniform sampler2D table;
layout(set = 0, binding = 2) readonly buffer Coords { vec4 coords[]; };
layout(set = 0, binding = 3) writeonly buffer Out { vec4 result[]; };
void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= p.count) return;
    vec4 a = textureLod(tf, coords[i].x, 0.0);
    vec2 b = textureLod(table, coords[i].yz, 0.0).rg;
    result[2u * i] = a;
    result[2u * i + 1u] = vec4(b, 0.0, 0.0);
}
"#;

const TEXEL_BUFFERS_COMP: &str = r#"#version 450
layout(local_size_x = 64) in;
layout(push_constant) uniform P { uint count; } p;
layout(set = 0, binding = 0) uniform samplerBuffer src;
layout(set = 0, binding = 1, r32f) uniform writeonly imageBuffer dst;
void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= p.count) return;
    imageStore(dst, int(i), vec4(texelFetch(src, int(i)).r * 2.0 + 1.0));
}
"#;

const WRITE_TARGET_COMP: &str = r#"#version 450
layout(local_size_x = 8, local_size_y = 8) in;
layout(set = 0, binding = 0, rgba32f) uniform image2D target;
void main() {
    ivec2 c = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(c, imageSize(target)))) return;
    imageStore(target, c, vec4(float(c.x), float(c.y), 7.0, 1.0));
}
"#;

const FILL_VALUE_COMP: &str = r#"#version 450
layout(local_size_x = 1) in;
layout(set = 0, binding = 0) buffer Out { uint value; };
void main() { value = VALUE; }
"#;

const FULLSCREEN_VERT: &str = r#"#version 450
void main() {
    vec2 p = vec2(float((gl_VertexIndex << 1) & 2), float(gl_VertexIndex & 2));
    gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
}
"#;

const TWO_TARGETS_FRAG: &str = r#"#version 450
layout(location = 0) out vec4 out_a;
layout(location = 1) out vec4 out_b;
void main() {
    out_a = vec4(1.0, 2.0, 3.0, 4.0);
    out_b = vec4(gl_FragCoord.xy, 5.0, 6.0);
}
"#;

const POINTS_VERT: &str = r#"#version 450
void main() {
    gl_Position = vec4(-0.875 + 0.25 * float(gl_VertexIndex), 0.0, 0.0, 1.0);
}
"#;

const POINT_TO_TRIANGLE_GEOM: &str = r#"#version 450
layout(points) in;
layout(triangle_strip, max_vertices = 3) out;
void main() {
    vec4 c = gl_in[0].gl_Position;
    gl_Position = c + vec4(-0.0625, -0.25, 0.0, 0.0); EmitVertex();
    gl_Position = c + vec4(0.0625, -0.25, 0.0, 0.0); EmitVertex();
    gl_Position = c + vec4(0.0, 0.25, 0.0, 0.0); EmitVertex();
    EndPrimitive();
}
"#;

const WHITE_FRAG: &str = r#"#version 450
layout(location = 0) out vec4 color;
void main() { color = vec4(1.0); }
"#;

/// Inline test shaders first, then volbench's own (for `common/…` includes).
fn source(path: &str) -> Option<&'static str> {
    const TEST: &[(&str, &str)] = &[
        ("test/count_groups.comp", COUNT_GROUPS_COMP),
        ("test/sample_3d.comp", SAMPLE_3D_COMP),
        ("test/fetch_3d_int.comp", FETCH_3D_INT_COMP),
        ("test/sample_tables.comp", SAMPLE_TABLES_COMP),
        ("test/texel_buffers.comp", TEXEL_BUFFERS_COMP),
        ("test/write_target.comp", WRITE_TARGET_COMP),
        ("test/fill_value.comp", FILL_VALUE_COMP),
        ("test/fullscreen.vert", FULLSCREEN_VERT),
        ("test/two_targets.frag", TWO_TARGETS_FRAG),
        ("test/points.vert", POINTS_VERT),
        ("test/point_to_triangle.geom", POINT_TO_TRIANGLE_GEOM),
        ("test/white.frag", WHITE_FRAG),
    ];
    TEST.iter().find(|(p, _)| *p == path).map(|(_, s)| *s).or_else(|| volbench::shaders::source(path))
}

fn module(ctx: &Arc<Context>, path: &str) -> ShaderModule {
    module_with(ctx, path, &[])
}

fn module_with(ctx: &Arc<Context>, path: &str, defines: &[(&str, &str)]) -> ShaderModule {
    let stage = ShaderStage::from_path(path).expect("stage from the file name");
    let spirv = compile_glsl(path, stage, defines, &source).unwrap_or_else(|e| panic!("{e}"));
    ShaderModule::new(ctx, path, stage, &spirv).expect("shader module")
}

fn compute_pipeline(ctx: &Arc<Context>, path: &str, sets: &[&DescriptorSet], push: u32) -> Pipeline {
    let shader = module(ctx, path);
    let layouts: Vec<_> = sets.iter().map(|s| s.layout).collect();
    Pipeline::compute(ctx, &ComputePipelineDesc { name: path, shader: &shader, push_constant_bytes: push, descriptor_layouts: &layouts })
        .expect("compute pipeline")
}

fn storage_readback(ctx: &Arc<Context>, name: &str, bytes: u64) -> Buffer {
    Buffer::new(ctx, BufferDesc { name: name.into(), size: bytes, usage: BufferUsage::STORAGE, memory: MemoryKind::Readback })
        .expect("readback buffer")
}

fn storage_upload(ctx: &Arc<Context>, name: &str, data: &[u8], counter: &mut UploadCounter) -> Buffer {
    let mut b = Buffer::new(ctx, BufferDesc::upload(name, data.len() as u64, BufferUsage::STORAGE)).expect("buffer");
    b.write(0, data, counter, UploadClass::Static).expect("write");
    b
}

fn words(bytes: &[u8]) -> Vec<u32> {
    bytes.chunks_exact(4).map(|c| u32::from_ne_bytes([c[0], c[1], c[2], c[3]])).collect()
}

fn floats(bytes: &[u8]) -> Vec<f32> {
    bytes.chunks_exact(4).map(|c| f32::from_ne_bytes([c[0], c[1], c[2], c[3]])).collect()
}

fn push_bytes(values: &[u32]) -> Vec<u8> {
    values.iter().flat_map(|v| v.to_ne_bytes()).collect()
}

const COMPUTE: Stages = Stages::COMPUTE;

// ---------------------------------------------------------------- 1. compute

#[test]
fn dispatch_beyond_the_group_limit_runs_every_group_once() {
    let ctx = context();
    let max_x = ctx.info.max_compute_work_group_count[0] as u64;
    // More groups than one dimension allows (65,535 on lavapipe); on devices
    // with a far larger limit the same count still exercises the path.
    let groups = max_x.min(65_535) + 34; // folds into a grid with one excess group
    let count = (groups * 32 - 5) as u32; // the last group is partly idle
    let guard = 64u64; // elements past `count` that nothing may touch
    let bytes = (count as u64 + guard) * 4;

    let hits = Buffer::new(
        &ctx,
        BufferDesc::device_local("hits", bytes, BufferUsage::STORAGE | BufferUsage::TRANSFER_SRC),
    )
    .unwrap();
    let groups_run = Buffer::new(
        &ctx,
        BufferDesc::device_local("groups run", 4, BufferUsage::STORAGE | BufferUsage::TRANSFER_SRC),
    )
    .unwrap();
    let readback = Buffer::new(&ctx, BufferDesc::readback("hits readback", bytes)).unwrap();
    let readback_groups = Buffer::new(&ctx, BufferDesc::readback("groups readback", 4)).unwrap();
    let desc = DescriptorSetDesc::new(&[(DescriptorKind::StorageBuffer, COMPUTE), (DescriptorKind::StorageBuffer, COMPUTE)]);
    let set = DescriptorSet::new(
        &ctx,
        "hits",
        &desc,
        &[DescriptorResource::StorageBuffer(&hits), DescriptorResource::StorageBuffer(&groups_run)],
    )
    .unwrap();
    let pipeline = compute_pipeline(&ctx, "test/count_groups.comp", &[&set], 8);
    let queries = FrameQueries::new(&ctx).unwrap();
    let mut counter = UploadCounter::default();

    let rec = CommandRecorder::new(&ctx, "dispatch test").unwrap();
    rec.begin().unwrap();
    queries.reset(&rec);
    rec.fill_buffer(&hits, 0);
    rec.fill_buffer(&groups_run, 0);
    rec.transfer_to_compute();
    rec.bind_compute(&pipeline, &[&set]).unwrap();
    rec.push_constants(&pipeline, &push_bytes(&[count, groups as u32]), &mut counter);
    queries.begin(&rec);
    let grid = rec.dispatch_groups(groups).unwrap();
    queries.end(&rec);
    rec.compute_to_transfer();
    rec.copy_buffer(&hits, &readback, bytes).unwrap();
    rec.copy_buffer(&groups_run, &readback_groups, 4).unwrap();
    rec.transfer_to_host();
    rec.submit_and_wait().unwrap();
    assert_no_validation(&ctx);

    assert_eq!(Some(grid), fold_groups(groups, ctx.info.max_compute_work_group_count));
    if max_x == 65_535 {
        assert_eq!(grid, [32_785, 2, 1], "lavapipe's limit folds into two rows, one group too many");
    }
    let launched = grid.iter().map(|&g| g as u64).product::<u64>();
    assert!(launched >= groups);
    let h = words(readback.read().unwrap());
    let wrong: Vec<(usize, u32)> = h[..count as usize].iter().copied().enumerate().filter(|&(_, v)| v != 1).take(5).collect();
    assert!(wrong.is_empty(), "elements not written exactly once (index, hits): {wrong:?}");
    assert!(h[count as usize..].iter().all(|&v| v == 0), "elements past the count were written");
    assert_eq!(words(readback_groups.read().unwrap())[0] as u64, groups, "excess groups must be skipped");
    assert_eq!(counter.frame_constant_bytes(), 8);

    let (_, stats) = queries.results().unwrap();
    assert_eq!(stats.is_some(), ctx.info.pipeline_statistics);
    if let Some(s) = stats {
        // Every launched invocation runs, including the skipped groups'.
        assert_eq!(s.compute_invocations, launched * 32, "{s:?}");
        assert_eq!((s.vertex_invocations, s.fragment_invocations), (0, 0), "{s:?}");
    }
    // A grid beyond a plain dispatch's limit is refused with a clear error
    // (and nothing is recorded).
    if let Some(too_many) = ctx.info.max_compute_work_group_count[0].checked_add(1) {
        rec.begin().unwrap();
        let err = rec.dispatch([too_many, 1, 1]).unwrap_err().to_string();
        assert!(err.contains("dispatch_groups"), "{err}");
        rec.submit_and_wait().unwrap();
    }
    assert_no_validation(&ctx);
}

// ---------------------------------------------------------------- 2. images

/// CPU reference for linear filtering with clamp-to-edge at texel
/// coordinate `p` (texel i's centre at i + 0.5) along one axis.
fn linear_taps(p: f64, n: u32) -> [(usize, f64); 2] {
    let t = p - 0.5;
    let i0 = t.floor();
    let a = t - i0;
    let clamp = |i: f64| i.clamp(0.0, n as f64 - 1.0) as usize;
    [(clamp(i0), 1.0 - a), (clamp(i0 + 1.0), a)]
}

fn trilinear(values: &[f64], size: [u32; 3], p: [f64; 3]) -> f64 {
    let (tx, ty, tz) = (linear_taps(p[0], size[0]), linear_taps(p[1], size[1]), linear_taps(p[2], size[2]));
    let mut sum = 0.0;
    for &(z, wz) in &tz {
        for &(y, wy) in &ty {
            for &(x, wx) in &tx {
                sum += wx * wy * wz * values[(z * size[1] as usize + y) * size[0] as usize + x];
            }
        }
    }
    sum
}

/// Sample points in texel units: every centre, points between centres at
/// multiples of 1/8 texel, and points near and past the edges (clamping).
/// With power-of-two sizes the normalised coordinates are exact in binary
/// and the weights exact at the device's 8 sub-texel bits, so any
/// difference from the CPU comes from the texel format, not the positions.
fn sample_points(size: [u32; 3]) -> Vec<[f64; 3]> {
    let mut pts = Vec::new();
    for z in 0..size[2] {
        for y in 0..size[1] {
            for x in 0..size[0] {
                pts.push([x as f64 + 0.5, y as f64 + 0.5, z as f64 + 0.5]);
            }
        }
    }
    let mut k = 0u32;
    for z in 0..size[2] {
        for y in 0..size[1] {
            for x in 0..size[0] {
                k += 1;
                let f = |i: u32, m: u32| i as f64 + 0.5 + ((k * m) % 8) as f64 / 8.0;
                pts.push([f(x, 3), f(y, 5), f(z, 7)]);
            }
        }
    }
    pts.extend([[0.125, 0.25, 0.0], [size[0] as f64, size[1] as f64, size[2] as f64], [0.0, size[1] as f64 - 0.125, 1.0]]);
    pts
}

#[test]
fn sampled_3d_images_match_cpu_trilinear_interpolation() {
    let ctx = context();
    let size = [8u32, 4, 2];
    let n = (size[0] * size[1] * size[2]) as usize;
    // Integer formats never filter linearly: the query must say so.
    assert!(!ctx.can_sample(Format::R16Sint, Filter::Linear));
    assert!(ctx.can_sample(Format::R16Sint, Filter::Nearest));

    let sampler = Sampler::linear_clamp(&ctx, "trilinear").unwrap();
    let points = sample_points(size);
    let coords: Vec<u8> = points
        .iter()
        .flat_map(|p| {
            let c = [p[0] / size[0] as f64, p[1] / size[1] as f64, p[2] / size[2] as f64, 0.0];
            c.map(|v| (v as f32).to_ne_bytes()).concat()
        })
        .collect();
    let mut counter = UploadCounter::default();
    let coords_buf = storage_upload(&ctx, "coords", &coords, &mut counter);
    let mut params = Buffer::new(&ctx, BufferDesc::upload("params", 16, BufferUsage::UNIFORM)).unwrap();
    params.write(0, &push_bytes(&[points.len() as u32, 0, 0, 0]), &mut counter, UploadClass::Static).unwrap();
    let out = storage_readback(&ctx, "samples", points.len() as u64 * 4);
    let desc = DescriptorSetDesc::default()
        .with(DescriptorKind::UniformBuffer, COMPUTE)
        .with(DescriptorKind::CombinedImageSampler, COMPUTE)
        .with(DescriptorKind::StorageBuffer, COMPUTE)
        .with(DescriptorKind::StorageBuffer, COMPUTE);

    // Texel values from a fixed pseudo-random sequence, per format: the
    // bytes to upload and the values the shader must see.
    let lcg = |i: usize| ((i as u64 * 2_654_435_761 + 12_345) % 1_000_003) as f64 / 1_000_003.0;
    type Encoded = (Vec<u8>, Vec<f64>);
    let formats: [(Format, f64, &dyn Fn() -> Encoded); 4] = [
        // R32F is filtered in f32: rounding only (values up to 100, whose
        // f32 spacing is 7.6e-6; a few roundings in the weighted sum).
        (Format::R32Float, 5e-5, &|| {
            let v: Vec<f32> = (0..n).map(|i| (lcg(i) * 200.0 - 100.0) as f32).collect();
            (v.iter().flat_map(|x| x.to_ne_bytes()).collect(), v.iter().map(|&x| x as f64).collect())
        }),
        // Normalised formats: the texels are exact; filtering may round the
        // result to the format's own precision (one unit in the last place).
        (Format::R16Unorm, 1.0 / 65_535.0, &|| {
            let v: Vec<u16> = (0..n).map(|i| (lcg(i) * 65_535.0) as u16).collect();
            (v.iter().flat_map(|x| x.to_ne_bytes()).collect(), v.iter().map(|&x| x as f64 / 65_535.0).collect())
        }),
        (Format::R16Snorm, 1.0 / 32_767.0, &|| {
            let v: Vec<i16> = (0..n).map(|i| (lcg(i) * 65_534.0 - 32_767.0) as i16).collect();
            (v.iter().flat_map(|x| x.to_ne_bytes()).collect(), v.iter().map(|&x| (x as f64 / 32_767.0).max(-1.0)).collect())
        }),
        // llvmpipe filters 8-bit texels in 8-bit fixed point, rounding each of
        // the three lerps to 1/255: up to 1.5/255 (a wrong texel or axis is
        // off by about 0.3 on these random values).
        (Format::R8Unorm, 1.5 / 255.0, &|| {
            let v: Vec<u8> = (0..n).map(|i| (lcg(i) * 255.0) as u8).collect();
            (v.clone(), v.iter().map(|&x| x as f64 / 255.0).collect())
        }),
    ];
    for (format, tolerance, encode) in formats {
        assert!(ctx.can_sample(format, Filter::Linear), "{format:?} must be filterable on this device");
        let (bytes, values) = encode();
        let before = counter;
        let volume = upload_texture(&ctx, &TextureDesc::d3(&format!("volume {format:?}"), size, format), &bytes, &mut counter).unwrap();
        assert_eq!(counter.since(&before).static_bytes(), bytes.len() as u64, "{format:?}: the upload counts as static bytes");
        assert_eq!(counter.since(&before).transfer_static, bytes.len() as u64);
        let set = DescriptorSet::new(
            &ctx,
            "sample 3d",
            &desc,
            &[
                DescriptorResource::UniformBuffer(&params),
                DescriptorResource::CombinedImageSampler(&volume, &sampler),
                DescriptorResource::StorageBuffer(&coords_buf),
                DescriptorResource::StorageBuffer(&out),
            ],
        )
        .unwrap();
        let pipeline = compute_pipeline(&ctx, "test/sample_3d.comp", &[&set], 0);
        let rec = CommandRecorder::new(&ctx, "sample 3d").unwrap();
        rec.begin().unwrap();
        rec.bind_compute(&pipeline, &[&set]).unwrap();
        rec.dispatch([(points.len() as u32).div_ceil(16), 1, 1]).unwrap();
        rec.compute_to_host();
        rec.submit_and_wait().unwrap();
        assert_no_validation(&ctx);
        let got = floats(out.read().unwrap());
        let mut worst = (0.0f64, 0usize);
        for (i, p) in points.iter().enumerate() {
            let want = trilinear(&values, size, *p);
            let err = (got[i] as f64 - want).abs();
            if err > worst.0 {
                worst = (err, i);
            }
            if i < n {
                // Texel centres return the texel itself.
                assert!((got[i] as f64 - values[i]).abs() <= tolerance, "{format:?} centre {i}");
            }
        }
        assert!(
            worst.0 <= tolerance,
            "{format:?}: worst error {:e} at {:?} (got {}, want {})",
            worst.0,
            points[worst.1],
            got[worst.1],
            trilinear(&values, size, points[worst.1])
        );
    }

    // An integer volume, fetched texel by texel: exact values.
    let v: Vec<i16> = (0..n).map(|i| (lcg(i) * 60_000.0 - 30_000.0) as i16).collect();
    let bytes: Vec<u8> = v.iter().flat_map(|x| x.to_ne_bytes()).collect();
    let volume = upload_texture(&ctx, &TextureDesc::d3("volume i16", size, Format::R16Sint), &bytes, &mut counter).unwrap();
    let nearest = Sampler::nearest_clamp(&ctx, "nearest").unwrap();
    let ints = storage_readback(&ctx, "ints", n as u64 * 4);
    let int_desc = DescriptorSetDesc::new(&[(DescriptorKind::CombinedImageSampler, COMPUTE), (DescriptorKind::StorageBuffer, COMPUTE)]);
    let set = DescriptorSet::new(
        &ctx,
        "fetch i16",
        &int_desc,
        &[DescriptorResource::CombinedImageSampler(&volume, &nearest), DescriptorResource::StorageBuffer(&ints)],
    )
    .unwrap();
    let pipeline = compute_pipeline(&ctx, "test/fetch_3d_int.comp", &[&set], 32);
    let rec = CommandRecorder::new(&ctx, "fetch i16").unwrap();
    rec.begin().unwrap();
    rec.bind_compute(&pipeline, &[&set]).unwrap();
    let push = push_bytes(&[n as u32, 0, 0, 0, size[0], size[1], size[2], 0]);
    rec.push_constants(&pipeline, &push, &mut counter);
    rec.dispatch([(n as u32).div_ceil(16), 1, 1]).unwrap();
    rec.compute_to_host();
    rec.submit_and_wait().unwrap();
    assert_no_validation(&ctx);
    let got: Vec<i32> = words(ints.read().unwrap()).into_iter().map(|w| w as i32).collect();
    assert_eq!(got, v.iter().map(|&x| x as i32).collect::<Vec<_>>());

    // Wrong data sizes are refused, naming the image.
    let err = upload_texture(&ctx, &TextureDesc::d3("short volume", size, Format::R8Unorm), &[0u8; 10], &mut counter)
        .err()
        .expect("10 bytes for 64 texels must be refused")
        .to_string();
    assert!(err.contains("short volume") && err.contains("64"), "{err}");
    assert_no_validation(&ctx);
}

#[test]
fn sampled_1d_and_2d_tables_match_cpu_interpolation() {
    let ctx = context();
    for f in [Format::Rgba32Float, Format::Rg32Float, Format::R32Float] {
        assert!(ctx.can_sample(f, Filter::Linear), "{f:?}");
    }
    let mut counter = UploadCounter::default();
    let tf_len = 16u32;
    let tf: Vec<[f32; 4]> = (0..tf_len).map(|i| [i as f32, (i * i) as f32 * 0.5, 100.0 - i as f32, (i % 3) as f32]).collect();
    let tf_bytes: Vec<u8> = tf.iter().flat_map(|t| t.map(f32::to_ne_bytes).concat()).collect();
    let tf_img = upload_texture(&ctx, &TextureDesc::d1("tf", tf_len, Format::Rgba32Float), &tf_bytes, &mut counter).unwrap();
    let (tw, th) = (8u32, 4u32);
    let table: Vec<[f32; 2]> = (0..tw * th).map(|i| [(i % tw) as f32 * 10.0 + (i / tw) as f32, -(i as f32)]).collect();
    let table_bytes: Vec<u8> = table.iter().flat_map(|t| t.map(f32::to_ne_bytes).concat()).collect();
    let table_img = upload_texture(&ctx, &TextureDesc::d2("table", tw, th, Format::Rg32Float), &table_bytes, &mut counter).unwrap();
    assert_eq!(counter.static_bytes(), (tf_bytes.len() + table_bytes.len()) as u64);

    // Texel-unit positions at multiples of 1/8 (exact weights), edges included.
    let pts: Vec<[f64; 3]> =
        (0..64).map(|k| [(k % 17) as f64 * 1.0 - 0.125 * (k % 5) as f64, (k % 9) as f64 * 0.875, (k % 5) as f64 * 0.75 + 0.125]).collect();
    let coords: Vec<u8> = pts
        .iter()
        .flat_map(|p| [p[0] / tf_len as f64, p[1] / tw as f64, p[2] / th as f64, 0.0].map(|v| (v as f32).to_ne_bytes()).concat())
        .collect();
    let coords_buf = storage_upload(&ctx, "coords", &coords, &mut counter);
    let out = storage_readback(&ctx, "table samples", pts.len() as u64 * 32);
    let sampler = Sampler::linear_clamp(&ctx, "linear").unwrap();
    let desc = DescriptorSetDesc::new(&[
        (DescriptorKind::CombinedImageSampler, COMPUTE),
        (DescriptorKind::CombinedImageSampler, COMPUTE),
        (DescriptorKind::StorageBuffer, COMPUTE),
        (DescriptorKind::StorageBuffer, COMPUTE),
    ]);
    let set = DescriptorSet::new(
        &ctx,
        "tables",
        &desc,
        &[
            DescriptorResource::CombinedImageSampler(&tf_img, &sampler),
            DescriptorResource::CombinedImageSampler(&table_img, &sampler),
            DescriptorResource::StorageBuffer(&coords_buf),
            DescriptorResource::StorageBuffer(&out),
        ],
    )
    .unwrap();
    let pipeline = compute_pipeline(&ctx, "test/sample_tables.comp", &[&set], 4);
    let rec = CommandRecorder::new(&ctx, "sample tables").unwrap();
    rec.begin().unwrap();
    rec.bind_compute(&pipeline, &[&set]).unwrap();
    rec.push_constants(&pipeline, &push_bytes(&[pts.len() as u32]), &mut counter);
    rec.dispatch([(pts.len() as u32).div_ceil(16), 1, 1]).unwrap();
    rec.compute_to_host();
    rec.submit_and_wait().unwrap();
    assert_no_validation(&ctx);
    let got = floats(out.read().unwrap());
    for (i, p) in pts.iter().enumerate() {
        let [a0, a1] = linear_taps(p[0], tf_len);
        for c in 0..4 {
            let want = a0.1 * tf[a0.0][c] as f64 + a1.1 * tf[a1.0][c] as f64;
            let g = got[8 * i + c] as f64;
            assert!((g - want).abs() <= 1e-5 * want.abs().max(1.0), "1D at {}: channel {c} got {g}, want {want}", p[0]);
        }
        let (tx, ty) = (linear_taps(p[1], tw), linear_taps(p[2], th));
        for c in 0..2 {
            let mut want = 0.0;
            for &(y, wy) in &ty {
                for &(x, wx) in &tx {
                    want += wx * wy * table[y * tw as usize + x][c] as f64;
                }
            }
            let g = got[8 * i + 4 + c] as f64;
            assert!((g - want).abs() <= 1e-5 * want.abs().max(1.0), "2D at {:?}: channel {c} got {g}, want {want}", &p[1..]);
        }
    }
}

// ---------------------------------------------------------------- 3. texel buffers

#[test]
fn texel_buffers_are_read_and_written_by_compute() {
    let ctx = context();
    let n = 1000u32;
    let mut counter = UploadCounter::default();
    let input: Vec<f32> = (0..n).map(|i| i as f32 * 0.25 - 7.0).collect();
    let in_bytes: Vec<u8> = input.iter().flat_map(|x| x.to_ne_bytes()).collect();
    let mut src = TexelBuffer::new(
        &ctx,
        BufferDesc::upload("texels in", in_bytes.len() as u64, BufferUsage::UNIFORM_TEXEL),
        Format::R32Float,
    )
    .unwrap();
    src.buffer.write(0, &in_bytes, &mut counter, UploadClass::Static).unwrap();
    assert_eq!(src.texels, n as u64);
    let dst = TexelBuffer::new(
        &ctx,
        BufferDesc {
            name: "texels out".into(),
            size: n as u64 * 4,
            usage: BufferUsage::STORAGE_TEXEL,
            memory: MemoryKind::Readback,
        },
        Format::R32Float,
    )
    .unwrap();
    let desc = DescriptorSetDesc::new(&[(DescriptorKind::UniformTexelBuffer, COMPUTE), (DescriptorKind::StorageTexelBuffer, COMPUTE)]);
    let set = DescriptorSet::new(
        &ctx,
        "texel buffers",
        &desc,
        &[DescriptorResource::UniformTexelBuffer(&src), DescriptorResource::StorageTexelBuffer(&dst)],
    )
    .unwrap();
    let pipeline = compute_pipeline(&ctx, "test/texel_buffers.comp", &[&set], 4);
    let rec = CommandRecorder::new(&ctx, "texel buffers").unwrap();
    rec.begin().unwrap();
    rec.bind_compute(&pipeline, &[&set]).unwrap();
    rec.push_constants(&pipeline, &push_bytes(&[n]), &mut counter);
    rec.dispatch([n.div_ceil(64), 1, 1]).unwrap();
    rec.compute_to_host();
    rec.submit_and_wait().unwrap();
    assert_no_validation(&ctx);
    let got = floats(dst.buffer.read().unwrap());
    for (i, (&g, &x)) in got.iter().zip(&input).enumerate() {
        assert_eq!(g, x * 2.0 + 1.0, "texel {i}");
    }

    // A size that is not a whole number of texels, and a usage without
    // texel-buffer bits, are errors naming the buffer.
    let err = TexelBuffer::new(&ctx, BufferDesc::upload("odd", 6, BufferUsage::UNIFORM_TEXEL), Format::R32Float)
        .err()
        .expect("6 bytes of R32F must be refused")
        .to_string();
    assert!(err.contains("'odd'"), "{err}");
    let err = TexelBuffer::new(&ctx, BufferDesc::upload("plain", 8, BufferUsage::STORAGE), Format::R32Float)
        .err()
        .expect("a buffer without texel usage must be refused")
        .to_string();
    assert!(err.contains("'plain'"), "{err}");
    assert_no_validation(&ctx);
}

// ---------------------------------------------------------------- 4. descriptor sets

#[test]
fn descriptor_sets_check_their_resources() {
    let ctx = context();
    let storage = Buffer::new(&ctx, BufferDesc::upload("ssbo", 64, BufferUsage::STORAGE)).unwrap();
    let desc = DescriptorSetDesc::new(&[(DescriptorKind::UniformBuffer, COMPUTE)]);
    let err = DescriptorSet::new(&ctx, "params", &desc, &[DescriptorResource::StorageBuffer(&storage)]).err().unwrap().to_string();
    assert!(err.contains("'params' binding 0") && err.contains("UniformBuffer"), "{err}");
    // The right kind but a buffer without the usage.
    let err = DescriptorSet::new(&ctx, "params", &desc, &[DescriptorResource::UniformBuffer(&storage)]).err().unwrap().to_string();
    assert!(err.contains("ssbo") && err.contains("lacks BufferUsage(UNIFORM) usage"), "{err}");
    let err = DescriptorSet::new(&ctx, "params", &desc, &[]).err().unwrap().to_string();
    assert!(err.contains("1 binding(s) described, 0 resource(s) given"), "{err}");
    // A sampled texture is not a storage image.
    let tex = Image::texture(&ctx, &TextureDesc::d2("tex", 4, 4, Format::R32Float)).unwrap();
    let desc = DescriptorSetDesc::new(&[(DescriptorKind::StorageImage, COMPUTE)]);
    let err = DescriptorSet::new(&ctx, "img", &desc, &[DescriptorResource::StorageImage(&tex)]).err().unwrap().to_string();
    assert!(err.contains("'tex' lacks STORAGE"), "{err}");
    // Integer texels cannot be filtered linearly.
    let ints = Image::texture(&ctx, &TextureDesc::d3("int volume", [2, 2, 2], Format::R16Sint)).unwrap();
    let linear = Sampler::linear_clamp(&ctx, "linear").unwrap();
    let desc = DescriptorSetDesc::new(&[(DescriptorKind::CombinedImageSampler, COMPUTE)]);
    let err = DescriptorSet::new(&ctx, "vol", &desc, &[DescriptorResource::CombinedImageSampler(&ints, &linear)])
        .err()
        .unwrap()
        .to_string();
    assert!(err.contains("'int volume'") && err.contains("nearest"), "{err}");
    // A pipeline with two sets wants two sets bound.
    let a = DescriptorSet::new(&ctx, "a", &DescriptorSetDesc::storage_buffers(1, COMPUTE), &[DescriptorResource::StorageBuffer(&storage)]).unwrap();
    let b = DescriptorSet::new(&ctx, "b", &DescriptorSetDesc::storage_buffers(1, COMPUTE), &[DescriptorResource::StorageBuffer(&storage)]).unwrap();
    let shader = module_with(&ctx, "test/fill_value.comp", &[("VALUE", "1u")]);
    let pipeline = Pipeline::compute(
        &ctx,
        &ComputePipelineDesc { name: "two sets", shader: &shader, push_constant_bytes: 0, descriptor_layouts: &[a.layout, b.layout] },
    )
    .unwrap();
    let rec = CommandRecorder::new(&ctx, "bind check").unwrap();
    rec.begin().unwrap();
    assert!(rec.bind_compute(&pipeline, &[&a]).is_err());
    assert!(rec.bind_graphics(&pipeline, &[&a, &b]).is_err(), "a compute pipeline is not bound as graphics");
    rec.bind_compute(&pipeline, &[&a, &b]).unwrap();
    drop(rec);
    assert_no_validation(&ctx);
}

// ---------------------------------------------------------------- 5. several targets, compute into the target

#[test]
fn one_draw_writes_two_colour_targets() {
    let ctx = context();
    let (w, h) = (8u32, 4u32);
    let a = Image::render_target(&ctx, "target a", w, h).unwrap();
    let b = Image::render_target(&ctx, "target b", w, h).unwrap();
    let (vs, fs) = (module(&ctx, "test/fullscreen.vert"), module(&ctx, "test/two_targets.frag"));
    let pipeline = Pipeline::graphics(
        &ctx,
        &GraphicsPipelineDesc {
            name: "two targets",
            vertex: &vs,
            geometry: None,
            fragment: &fs,
            vertex_stride: 0,
            attributes: &[],
            topology: Topology::TriangleList,
            primitive_restart: false,
            cull: Cull::None,
            front_face: Winding::CounterClockwise,
            targets: &[ColorTarget::rgba32f(Blend::None), ColorTarget::rgba32f(Blend::None)],
            depth_test: false,
            depth_clamp: false,
            push_constant_bytes: 0,
            descriptor_layouts: &[],
        },
    )
    .unwrap();
    let rec = CommandRecorder::new(&ctx, "two targets").unwrap();
    rec.begin().unwrap();
    rec.begin_rendering_targets(&[ColorAttachment { image: &a, clear: Some([0.0; 4]) }, ColorAttachment { image: &b, clear: Some([0.0; 4]) }])
        .unwrap();
    rec.bind_graphics(&pipeline, &[]).unwrap();
    rec.draw(3);
    rec.end_rendering();
    rec.submit_and_wait().unwrap();
    let (pa, pb) = (a.read_rgba32f(&ctx).unwrap(), b.read_rgba32f(&ctx).unwrap());
    assert_no_validation(&ctx);
    for y in 0..h as usize {
        for x in 0..w as usize {
            let i = y * w as usize + x;
            assert_eq!(pa[i], [1.0, 2.0, 3.0, 4.0], "target a at ({x}, {y})");
            assert_eq!(pb[i], [x as f32 + 0.5, y as f32 + 0.5, 5.0, 6.0], "target b at ({x}, {y})");
        }
    }

    // Targets of different sizes cannot share a pass.
    let small = Image::render_target(&ctx, "small", 4, 4).unwrap();
    rec.begin().unwrap();
    let err = rec
        .begin_rendering_targets(&[ColorAttachment { image: &a, clear: Some([0.0; 4]) }, ColorAttachment { image: &small, clear: None }])
        .unwrap_err()
        .to_string();
    assert!(err.contains("small") && err.contains("differ in size"), "{err}");
    drop(rec);
    assert_no_validation(&ctx);
}

#[test]
fn compute_writes_the_render_target_and_readback_follows_either_path() {
    let ctx = context();
    let (w, h) = (13u32, 7u32);
    let target = Image::render_target(&ctx, "final image", w, h).unwrap();
    assert!(target.is_storage());
    let desc = DescriptorSetDesc::new(&[(DescriptorKind::StorageImage, COMPUTE)]);
    let set = DescriptorSet::new(&ctx, "final image", &desc, &[DescriptorResource::StorageImage(&target)]).unwrap();
    let pipeline = compute_pipeline(&ctx, "test/write_target.comp", &[&set], 0);
    let rec = CommandRecorder::new(&ctx, "compute target").unwrap();
    let expect_compute = |pixels: &[[f32; 4]]| {
        for y in 0..h as usize {
            for x in 0..w as usize {
                assert_eq!(pixels[y * w as usize + x], [x as f32, y as f32, 7.0, 1.0], "({x}, {y})");
            }
        }
    };
    // Render (clear), then compute over it, then read.
    rec.begin().unwrap();
    rec.begin_rendering(&target, [3.0; 4]);
    rec.end_rendering();
    rec.image_barrier(&target, ImageUse::ComputeStorage);
    rec.bind_compute(&pipeline, &[&set]).unwrap();
    rec.dispatch([w.div_ceil(8), h.div_ceil(8), 1]).unwrap();
    rec.submit_and_wait().unwrap();
    expect_compute(&target.read_rgba32f(&ctx).unwrap());
    assert_no_validation(&ctx);
    // Render after the compute pass and the readback: the render wins.
    rec.begin().unwrap();
    rec.begin_rendering(&target, [9.0; 4]);
    rec.end_rendering();
    rec.submit_and_wait().unwrap();
    assert!(target.read_rgba32f(&ctx).unwrap().iter().all(|p| *p == [9.0; 4]));
    // Compute straight after a readback, discarding the contents.
    rec.begin().unwrap();
    rec.image_barrier_discard(&target, ImageUse::ComputeStorage);
    rec.bind_compute(&pipeline, &[&set]).unwrap();
    rec.dispatch([w.div_ceil(8), h.div_ceil(8), 1]).unwrap();
    rec.submit_and_wait().unwrap();
    expect_compute(&target.read_rgba32f(&ctx).unwrap());
    assert_no_validation(&ctx);
}

// ---------------------------------------------------------------- 6. geometry shaders, features

#[test]
fn a_geometry_shader_expands_points_into_counted_triangles() {
    let ctx = context();
    let need = DeviceFeatures { geometry_shader: true, pipeline_statistics_query: true, ..DeviceFeatures::default() };
    assert_eq!(need.missing_from(&ctx.info.features), Vec::<&str>::new(), "lavapipe has both");
    assert_eq!(need.missing_from(&DeviceFeatures::default()), vec!["geometryShader", "pipelineStatisticsQuery"]);
    let info = serde_json::to_value(&ctx.info).unwrap();
    assert_eq!(info["features"]["geometry_shader"], serde_json::Value::Bool(true), "{info}");

    // Built through the pipeline cache, with a geometry stage in the key.
    let cache = PipelineCache::new(&ctx, source).unwrap();
    let key = PipelineKey::Graphics(GraphicsPipelineKey {
        vertex: ShaderKey::new("test/points.vert", ShaderStage::Vertex, &[]),
        geometry: Some(ShaderKey::new("test/point_to_triangle.geom", ShaderStage::Geometry, &[])),
        fragment: ShaderKey::new("test/white.frag", ShaderStage::Fragment, &[]),
        state: GraphicsState {
            vertex_stride: 0,
            attributes: vec![],
            topology: Topology::PointList,
            primitive_restart: false,
            cull: Cull::None,
            front_face: Winding::CounterClockwise,
            targets: vec![ColorTarget::rgba32f(Blend::Additive)],
            depth_test: false,
            depth_clamp: false,
        },
        push_constant_bytes: 0,
        sets: vec![],
    });
    let pipeline = cache.get(&key).unwrap();
    assert!(pipeline.push_stages.contains(Stages::GEOMETRY));
    let (w, h) = (64u32, 16u32);
    let target = Image::render_target(&ctx, "points", w, h).unwrap();
    let queries = FrameQueries::new(&ctx).unwrap();
    let rec = CommandRecorder::new(&ctx, "geometry").unwrap();
    rec.begin().unwrap();
    queries.reset(&rec);
    rec.begin_rendering(&target, [0.0; 4]);
    queries.begin(&rec);
    rec.bind_graphics(&pipeline, &[]).unwrap();
    rec.draw(8);
    queries.end(&rec);
    rec.end_rendering();
    rec.submit_and_wait().unwrap();
    let pixels = target.read_rgba32f(&ctx).unwrap();
    assert_no_validation(&ctx);
    let (_, stats) = queries.results().unwrap();
    let s = stats.expect("pipeline statistics on lavapipe");
    assert_eq!((s.input_vertices, s.input_primitives, s.vertex_invocations), (8, 8, 8), "{s:?}");
    assert_eq!((s.geometry_invocations, s.geometry_primitives), (8, 8), "{s:?}");
    assert_eq!(s.compute_invocations, 0);
    // Eight separate triangles, none overlapping (additive blend: a pixel
    // covered twice would read 2), one per point along the row.
    let covered: Vec<usize> = (0..pixels.len()).filter(|&i| pixels[i][0] > 0.0).collect();
    assert!(pixels.iter().all(|p| p[0] == 0.0 || p[0] == 1.0));
    assert!(!covered.is_empty());
    let columns: std::collections::BTreeSet<usize> = covered.iter().map(|i| i % w as usize / 8).collect();
    assert_eq!(columns.len(), 8, "one triangle in each eighth of the row");
    assert!(s.fragment_invocations >= covered.len() as u64, "{s:?} vs {} pixels", covered.len());
}

// ---------------------------------------------------------------- 7. pipeline cache

#[test]
fn the_pipeline_cache_shares_equal_keys_and_ids_are_stable() {
    let ctx = context();
    let sets = vec![DescriptorSetDesc::storage_buffers(1, COMPUTE)];
    let key = |value: &str| {
        PipelineKey::Compute(ComputePipelineKey {
            shader: ShaderKey::new("test/fill_value.comp", ShaderStage::Compute, &[("VALUE", value), ("UNUSED", "x")]),
            push_constant_bytes: 0,
            sets: sets.clone(),
        })
    };
    let (k1, k2) = (key("11u"), key("22u"));
    // Define order does not matter; the id is a pure function of the key.
    let reordered = PipelineKey::Compute(ComputePipelineKey {
        shader: ShaderKey::new("test/fill_value.comp", ShaderStage::Compute, &[("UNUSED", "x"), ("VALUE", "11u")]),
        push_constant_bytes: 0,
        sets: sets.clone(),
    });
    assert_eq!(k1, reordered);
    assert_eq!(k1.id(), reordered.id());
    assert_ne!(k1.id(), k2.id());
    assert_eq!(k1.id().len(), 16);
    assert!(k1.id().chars().all(|c| c.is_ascii_hexdigit() && !c.is_ascii_uppercase()));
    assert_eq!(
        k1.canonical(),
        "volbench-pipeline-v1;compute;shader(20:test/fill_value.comp,3,6:UNUSED,1:x,5:VALUE,3:11u,);push=0;sets[[0/32,]]"
    );
    // FNV-1a of the canonical text above: fixed forever (a change here means
    // every recorded id changes; bump the version tag instead).
    assert_eq!(k1.id(), format!("{:016x}", volbench::vk::fnv1a64(k1.canonical().as_bytes())));
    assert_eq!(k1.id(), "f0ccc9af09d77a09");

    let cache = PipelineCache::new(&ctx, source).unwrap();
    assert!(cache.is_empty());
    let p1 = cache.get(&k1).unwrap();
    let p1_again = cache.get(&reordered).unwrap();
    let p2 = cache.get(&k2).unwrap();
    assert!(Arc::ptr_eq(&p1, &p1_again), "an equal key gives the same pipeline");
    assert!(!Arc::ptr_eq(&p1, &p2));
    assert_eq!(cache.len(), 2);
    assert_ne!(cache.raw, Default::default(), "a live cache handle, not null");

    // The define really changes the pipeline, and a set made from an equal
    // description binds to the cache's layout.
    for (p, want) in [(&p1, 11u32), (&p2, 22)] {
        let out = storage_readback(&ctx, "value", 4);
        let set = DescriptorSet::new(&ctx, "value", &sets[0], &[DescriptorResource::StorageBuffer(&out)]).unwrap();
        let rec = CommandRecorder::new(&ctx, "cached pipeline").unwrap();
        rec.begin().unwrap();
        rec.bind_compute(p, &[&set]).unwrap();
        rec.dispatch([1, 1, 1]).unwrap();
        rec.compute_to_host();
        rec.submit_and_wait().unwrap();
        assert_eq!(words(out.read().unwrap())[0], want);
    }
    // A shader that does not compile is an error naming it, and not cached.
    let bad = PipelineKey::Compute(ComputePipelineKey {
        shader: ShaderKey::new("test/fill_value.comp", ShaderStage::Compute, &[]),
        push_constant_bytes: 0,
        sets: sets.clone(),
    });
    let err = cache.get(&bad).err().expect("VALUE undefined").to_string();
    assert!(err.contains("shaders/test/fill_value.comp"), "{err}");
    assert_eq!(cache.len(), 2);
    assert_no_validation(&ctx);
}

// ---------------------------------------------------------------- 8. never hang

#[test]
fn dropping_an_unsubmitted_recorder_returns_promptly() {
    // Hold the lock while the worker uses the context: the command pool is
    // shared, and Vulkan requires it to be used from one thread at a time.
    let guard = context();
    let ctx = guard.clone();
    let (tx, rx) = mpsc::channel();
    let worker = std::thread::spawn(move || {
        // Begun, never submitted.
        let rec = CommandRecorder::new(&ctx, "never submitted").unwrap();
        rec.begin().unwrap();
        assert_eq!(rec.wait().unwrap(), Duration::ZERO, "nothing to wait for");
        drop(rec);
        // Never even begun; a failed submit (without begin) leaves nothing pending.
        let rec = CommandRecorder::new(&ctx, "never begun").unwrap();
        assert!(rec.submit().is_err());
        assert!(!rec.is_pending());
        drop(rec);
        // A panic between creating a recorder and its first submit.
        let panicked = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            let rec = CommandRecorder::new(&ctx, "panics before submit").unwrap();
            rec.begin().unwrap();
            panic!("simulated failure while recording");
        }));
        assert!(panicked.is_err());
        // Query results of a frame that never ran: an error, not a wait.
        let queries = FrameQueries::new(&ctx).unwrap();
        let rec = CommandRecorder::new(&ctx, "reset only").unwrap();
        rec.begin().unwrap();
        queries.reset(&rec);
        rec.submit_and_wait().unwrap();
        let err = queries.results().unwrap_err().to_string();
        assert!(err.contains("not available"), "{err}");
        let _ = tx.send(());
    });
    // Watchdog: before the fix each drop waited forever on an unsignalled fence.
    rx.recv_timeout(Duration::from_secs(30)).expect("dropping unsubmitted recorders must not wait");
    worker.join().unwrap();
    assert_no_validation(&guard);
}

#[test]
fn fence_time_outs_are_bounded_and_configurable() {
    let ctx = context();
    assert_eq!(ctx.fence_timeout, volbench::vk::fence_timeout_from_env().unwrap());
    assert_eq!(DEFAULT_FENCE_TIMEOUT, Duration::from_secs(60));
    assert_eq!(parse_fence_timeout("2.5").unwrap(), Duration::from_millis(2500));
    assert_eq!(parse_fence_timeout(" 60 ").unwrap(), Duration::from_secs(60));
    for bad in ["0", "-1", "abc", "", "inf", "NaN", "1e9"] {
        let err = parse_fence_timeout(bad).unwrap_err();
        assert!(matches!(err, VkError::Env { .. }), "{bad}");
        assert!(err.to_string().contains("VOLBENCH_FENCE_TIMEOUT_S"), "{err}");
    }
}

// ---------------------------------------------------------------- 9. VOLBENCH_VALIDATION

#[test]
fn validation_switch_accepts_the_usual_spellings_and_rejects_the_rest() {
    for on in ["1", "true", "TRUE", "True", "yes", "YES", "on", "On", " yes "] {
        assert!(parse_env_flag("VOLBENCH_VALIDATION", on).unwrap(), "{on}");
    }
    for off in ["0", "false", "FALSE", "no", "No", "off", "OFF", ""] {
        assert!(!parse_env_flag("VOLBENCH_VALIDATION", off).unwrap(), "{off}");
    }
    for bad in ["2", "y", "enable", "truthy", "-1", "yes please"] {
        let err = parse_env_flag("VOLBENCH_VALIDATION", bad).unwrap_err().to_string();
        assert!(err.contains("VOLBENCH_VALIDATION") && err.contains(&format!("{bad:?}")), "{err}");
    }
    // The same rule through ContextDesc, with a fake environment.
    let env = |pairs: &'static [(&'static str, &'static str)]| {
        move |name: &str| pairs.iter().find(|(k, _)| *k == name).map(|(_, v)| v.to_string())
    };
    let d = ContextDesc::from_vars(&env(&[("VOLBENCH_VALIDATION", "yes"), ("VOLBENCH_DEVICE", "llvm")])).unwrap();
    assert!(d.validation, "'yes' turns validation on (it was silently off)");
    assert_eq!(d.device.as_deref(), Some("llvm"));
    assert!(!ContextDesc::from_vars(&env(&[])).unwrap().validation);
    assert!(!ContextDesc::from_vars(&env(&[("VOLBENCH_VALIDATION", "off")])).unwrap().validation);
    let err = ContextDesc::from_vars(&env(&[("VOLBENCH_VALIDATION", "sure")])).unwrap_err().to_string();
    assert!(err.contains("VOLBENCH_VALIDATION") && err.contains("\"sure\""), "{err}");
}

/// The copy helpers check sizes before recording: a copy larger than either
/// buffer, or of zero bytes, is an error naming both buffers, and nothing
/// reaches the device (no validation message).
#[test]
fn buffer_copies_check_their_sizes() {
    let ctx = context();
    let mut counter = UploadCounter::default();
    let small = Buffer::new(&ctx, BufferDesc::readback("small readback", 16)).unwrap();
    let mut big = Buffer::new(&ctx, BufferDesc::upload("big source", 64, BufferUsage::TRANSFER_SRC)).unwrap();
    big.write(0, &[7u8; 64], &mut counter, UploadClass::Static).unwrap();
    let rec = CommandRecorder::new(&ctx, "copy sizes").unwrap();
    rec.begin().unwrap();
    for bytes in [0, 32, 65] {
        let e = rec.copy_buffer(&big, &small, bytes).unwrap_err().to_string();
        assert!(e.contains("big source") && e.contains("small readback") && e.contains(&format!("{bytes} bytes")), "{e}");
    }
    let e = rec.copy_to_device(&big, &small, 17, &mut counter, UploadClass::Static).unwrap_err().to_string();
    assert!(e.contains("more than a buffer holds"), "{e}");
    rec.copy_buffer(&big, &small, 16).unwrap();
    rec.transfer_to_host();
    rec.submit_and_wait().unwrap();
    assert_eq!(small.read().unwrap()[..16], [7u8; 16]);
    assert_no_validation(&ctx);
}

/// `storage_target` knows where its target may be nonzero only while every
/// write to it went through it: the rectangle it was given (the whole
/// image when that covers it), forgotten by any barrier into a state that
/// may write the image (a render pass, a compute write, a discard), kept
/// across read-only uses (a readback).
#[test]
fn storage_target_tracks_where_the_image_may_be_nonzero() {
    let ctx = context();
    let target = Image::render_target(&ctx, "tracked target", 40, 30).unwrap();
    assert_eq!(target.zero_outside(), None);
    let rec = CommandRecorder::new(&ctx, "storage target").unwrap();
    rec.begin().unwrap();
    rec.storage_target(&target, [3, 4, 20, 10]);
    assert_eq!(target.zero_outside(), Some([3, 4, 20, 10]));
    rec.image_barrier(&target, ImageUse::TransferSrc);
    assert_eq!(target.zero_outside(), Some([3, 4, 20, 10]), "a read keeps it");
    rec.storage_target(&target, [1, 1, 0, 0]);
    assert_eq!(target.zero_outside(), Some([1, 1, 0, 0]), "an empty rectangle: all zero");
    rec.storage_target(&target, [0, 0, 39, 29]);
    assert_eq!(target.zero_outside(), Some([0, 0, 39, 29]), "the whole image");
    for write in [ImageUse::ColorAttachment, ImageUse::ComputeStorage] {
        rec.storage_target(&target, [2, 2, 5, 5]);
        rec.image_barrier(&target, write);
        assert_eq!(target.zero_outside(), None, "{write:?}");
    }
    rec.storage_target(&target, [2, 2, 5, 5]);
    rec.begin_rendering(&target, [0.0; 4]);
    rec.end_rendering();
    assert_eq!(target.zero_outside(), None, "a render pass");
    rec.storage_target(&target, [2, 2, 5, 5]);
    rec.image_barrier_discard(&target, ImageUse::TransferSrc);
    assert_eq!(target.zero_outside(), None, "a discard");
    rec.submit_and_wait().unwrap();
    assert!(ctx.validation_messages().is_empty(), "{:?}", ctx.validation_messages());
}
