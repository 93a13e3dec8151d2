#!/usr/bin/env python3
"""VTK as a peer of volbench (`volbench suite --peers vtk`).

volbench writes a scene file (JSON: the dataset as a legacy VTK file, the
renderer to use, image size, one camera per warm-up and timed frame plus the
reference view, and the transfer function already encoded for the renderer's
opacity model); this script renders it with VTK offscreen (EGL on Mesa's
llvmpipe when there is no GPU), times every frame as Render() plus
WaitForCompletion() (VTK's glFinish), and writes a result file (JSON) and the
reference view's image (raw RGBA8, top row first) where the scene says.

Usage:
    vtk_peer.py --scene SCENE.json     render, write the result and image
    vtk_peer.py --check                VTK imports and an offscreen window opens

Exit status 0 on success; otherwise a one-line reason on stderr.
The script does nothing volbench did not ask for: no network, no other files.
"""

import json
import math
import os
import sys
import time

SCENE_FORMAT = "volbench-peer-scene"
RESULT_FORMAT = "volbench-peer-result"
VERSION = 1

# VTK renderer names (volbench's peer keys) and how each is built.
RENDERERS = {
    "projected-tetrahedra": ("tet-mesh", "vtkProjectedTetrahedraMapper"),
    "unstructured-raycast": ("tet-mesh", "vtkUnstructuredGridVolumeRayCastMapper"),
    "gpu-raycast": ("volume", "vtkGPUVolumeRayCastMapper"),
    "fixed-point-raycast": ("volume", "vtkFixedPointVolumeRayCastMapper"),
}


class PeerError(Exception):
    pass


def fail(msg):
    print("vtk_peer: " + msg, file=sys.stderr)
    sys.exit(2)


def import_vtk():
    # EGL first: headless machines have no X server, and VTK's X window
    # complains before falling back.
    os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    try:
        import vtkmodules.all as vtk  # noqa: F401
        from vtkmodules.util import numpy_support
        import numpy
    except ImportError as e:
        raise PeerError("cannot import VTK / numpy (%s); run scripts/install-vtk.sh" % e)
    return vtk, numpy_support, numpy


def open_window(vtk, width, height):
    rw = vtk.vtkRenderWindow()
    rw.SetOffScreenRendering(1)
    rw.SetSize(width, height)
    rw.SetMultiSamples(0)
    rw.SetAlphaBitPlanes(1)
    ren = vtk.vtkRenderer()
    ren.SetBackground(0.0, 0.0, 0.0)
    ren.SetBackgroundAlpha(0.0)
    rw.AddRenderer(ren)
    return rw, ren


def gl_renderer(rw):
    caps = rw.ReportCapabilities() or ""
    for line in caps.splitlines():
        if line.startswith("OpenGL renderer string:"):
            return line.split(":", 1)[1].strip()
    return "unknown"


def need(obj, key, kind, where):
    if not isinstance(obj, dict) or key not in obj:
        raise PeerError("scene: missing '%s' in %s" % (key, where))
    v = obj[key]
    if kind is float:
        if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v):
            raise PeerError("scene: '%s' in %s must be a finite number, got %r" % (key, where, v))
        return float(v)
    if kind is int:
        if not isinstance(v, int) or isinstance(v, bool) or v < 0:
            raise PeerError("scene: '%s' in %s must be a non-negative integer, got %r" % (key, where, v))
        return v
    if not isinstance(v, kind):
        raise PeerError("scene: '%s' in %s has the wrong type (%s)" % (key, where, type(v).__name__))
    return v


def vec3(obj, key, where):
    v = need(obj, key, list, where)
    if len(v) != 3 or not all(isinstance(x, (int, float)) and math.isfinite(x) for x in v):
        raise PeerError("scene: '%s' in %s must be three finite numbers" % (key, where))
    return [float(x) for x in v]


def set_camera(vtk_cam, cam, where):
    """volbench's camera (scene::Camera): eye, target, up, projection, near, far."""
    vtk_cam.SetPosition(*vec3(cam, "eye", where))
    vtk_cam.SetFocalPoint(*vec3(cam, "target", where))
    vtk_cam.SetViewUp(*vec3(cam, "up", where))
    proj = need(cam, "projection", dict, where)
    kind = need(proj, "kind", str, where + ".projection")
    if kind == "perspective":
        vtk_cam.ParallelProjectionOff()
        # volbench's field of view is vertical, as VTK's view angle.
        vtk_cam.SetViewAngle(need(proj, "fovy_deg", float, where + ".projection"))
    elif kind == "orthographic":
        vtk_cam.ParallelProjectionOn()
        vtk_cam.SetParallelScale(0.5 * need(proj, "height", float, where + ".projection"))
    else:
        raise PeerError("scene: unknown projection kind '%s' in %s" % (kind, where))
    vtk_cam.SetClippingRange(need(cam, "near", float, where), need(cam, "far", float, where))


def build_property(vtk, tf):
    """Colour and opacity exactly as volbench encoded them for this renderer."""
    prop = vtk.vtkVolumeProperty()
    color = vtk.vtkColorTransferFunction()
    opacity = vtk.vtkPiecewiseFunction()
    for i, p in enumerate(need(tf, "color_points", list, "transfer_function")):
        if len(p) != 4:
            raise PeerError("scene: transfer_function.color_points[%d] must be [scalar, r, g, b]" % i)
        color.AddRGBPoint(*[float(x) for x in p])
    for i, p in enumerate(need(tf, "opacity_points", list, "transfer_function")):
        if len(p) != 2:
            raise PeerError("scene: transfer_function.opacity_points[%d] must be [scalar, opacity]" % i)
        opacity.AddPoint(float(p[0]), float(p[1]))
    color.ClampingOn()
    opacity.ClampingOn()
    prop.SetColor(color)
    prop.SetScalarOpacity(opacity)
    prop.SetScalarOpacityUnitDistance(need(tf, "unit_distance", float, "transfer_function"))
    prop.SetInterpolationTypeToLinear()
    prop.ShadeOff()
    return prop


def read_data(vtk, dataset):
    path = need(dataset, "file", str, "dataset")
    fmt = need(dataset, "format", str, "dataset")
    if not os.path.isfile(path):
        raise PeerError("scene: dataset file %s does not exist" % path)
    if fmt == "vtk-legacy-unstructured-grid":
        reader = vtk.vtkUnstructuredGridReader()
    elif fmt == "vtk-legacy-structured-points":
        reader = vtk.vtkStructuredPointsReader()
    else:
        raise PeerError("scene: unknown dataset format '%s'" % fmt)
    reader.SetFileName(path)
    reader.Update()
    data = reader.GetOutput()
    if data is None or data.GetNumberOfPoints() == 0 or data.GetPointData().GetScalars() is None:
        raise PeerError("%s: VTK read no points or no point scalars" % path)
    return data


def build_mapper(vtk, renderer, data, scene):
    if renderer == "projected-tetrahedra":
        m = vtk.vtkProjectedTetrahedraMapper()
    elif renderer == "unstructured-raycast":
        m = vtk.vtkUnstructuredGridVolumeRayCastMapper()
        # Exact integration of linear colour and attenuation along each
        # segment (volbench's reference model); the default (partial
        # pre-integration) crashes on zero-volume tets (PLATFORM.md).
        m.SetRayIntegrator(vtk.vtkUnstructuredGridLinearRayIntegrator())
        m.SetImageSampleDistance(1.0)
        m.AutoAdjustSampleDistancesOff()
    elif renderer == "gpu-raycast":
        m = vtk.vtkGPUVolumeRayCastMapper()
        m.AutoAdjustSampleDistancesOff()
        m.LockSampleDistanceToInputSpacingOff()
        m.SetSampleDistance(need(scene, "sample_distance", float, "scene"))
        m.SetImageSampleDistance(1.0)
        m.SetUseJittering(0)
    elif renderer == "fixed-point-raycast":
        m = vtk.vtkFixedPointVolumeRayCastMapper()
        m.AutoAdjustSampleDistancesOff()
        m.LockSampleDistanceToInputSpacingOff()
        m.SetSampleDistance(need(scene, "sample_distance", float, "scene"))
        m.SetInteractiveSampleDistance(need(scene, "sample_distance", float, "scene"))
        m.SetImageSampleDistance(1.0)
    else:
        raise PeerError("scene: unknown renderer '%s' (known: %s)" % (renderer, ", ".join(sorted(RENDERERS))))
    m.SetInputData(data)
    return m


def render(scene):
    if need(scene, "format", str, "scene") != SCENE_FORMAT or need(scene, "version", int, "scene") != VERSION:
        raise PeerError("scene: not a %s v%d file" % (SCENE_FORMAT, VERSION))
    renderer = need(scene, "renderer", str, "scene")
    if renderer not in RENDERERS:
        raise PeerError("scene: unknown renderer '%s' (known: %s)" % (renderer, ", ".join(sorted(RENDERERS))))
    dataset = need(scene, "dataset", dict, "scene")
    kind, cls = RENDERERS[renderer]
    if need(dataset, "kind", str, "dataset") != kind:
        raise PeerError("scene: renderer '%s' renders %s data, the dataset is %s" % (renderer, kind, dataset["kind"]))
    width, height = need(scene, "width", int, "scene"), need(scene, "height", int, "scene")
    warmup, frames = need(scene, "warmup", int, "scene"), need(scene, "frames", int, "scene")
    if not (0 < width <= 16384 and 0 < height <= 16384):
        raise PeerError("scene: image size %dx%d out of range" % (width, height))
    cameras = need(scene, "cameras", list, "scene")
    if frames < 1 or len(cameras) != warmup + frames:
        raise PeerError("scene: %d cameras for %d warm-up and %d timed frames" % (len(cameras), warmup, frames))
    out = need(scene, "output", dict, "scene")
    result_path, image_path = need(out, "result", str, "output"), need(out, "image", str, "output")

    vtk, numpy_support, numpy = import_vtk()
    t0 = time.perf_counter()
    data = read_data(vtk, dataset)
    load_ms = (time.perf_counter() - t0) * 1e3
    t0 = time.perf_counter()
    rw, ren = open_window(vtk, width, height)
    volume = vtk.vtkVolume()
    volume.SetMapper(build_mapper(vtk, renderer, data, scene))
    volume.SetProperty(build_property(vtk, need(scene, "transfer_function", dict, "scene")))
    ren.AddVolume(volume)
    cam = ren.GetActiveCamera()
    setup_ms = (time.perf_counter() - t0) * 1e3

    samples = []
    for f, c in enumerate(cameras):
        set_camera(cam, c, "cameras[%d]" % f)
        t0 = time.perf_counter()
        rw.Render()
        rw.WaitForCompletion()
        samples.append((time.perf_counter() - t0) * 1e3)

    # The reference view (volbench's orbit angle 0), untimed.
    set_camera(cam, need(scene, "reference_camera", dict, "scene"), "reference_camera")
    rw.Render()
    rw.WaitForCompletion()
    grab = vtk.vtkWindowToImageFilter()
    grab.SetInput(rw)
    grab.SetInputBufferTypeToRGBA()
    grab.ReadFrontBufferOff()
    grab.ShouldRerenderOff()
    grab.Update()
    img = grab.GetOutput()
    dims = img.GetDimensions()
    if dims[0] != width or dims[1] != height:
        raise PeerError("VTK returned a %dx%d image for a %dx%d window" % (dims[0], dims[1], width, height))
    rgba = numpy_support.vtk_to_numpy(img.GetPointData().GetScalars()).reshape(height, width, 4)
    # VTK's rows go bottom-up; volbench's top-down.
    rgba = numpy.ascontiguousarray(rgba[::-1, :, :], dtype=numpy.uint8)
    with open(image_path, "wb") as fh:
        fh.write(rgba.tobytes())

    result = {
        "format": RESULT_FORMAT,
        "version": VERSION,
        "peer": "vtk",
        "renderer": renderer,
        "class": cls,
        "library_version": vtk.vtkVersion.GetVTKVersion(),
        "window": rw.GetClassName(),
        "gl_renderer": gl_renderer(rw),
        "load_ms": load_ms,
        "setup_ms": setup_ms,
        "warmup_ms": samples[:warmup],
        "frame_ms": samples[warmup:],
        "image": {"file": os.path.basename(image_path), "width": width, "height": height, "format": "rgba8", "rows": "top-down"},
    }
    tmp = result_path + ".tmp"
    with open(tmp, "w") as fh:
        json.dump(result, fh, indent=1)
    os.replace(tmp, result_path)


def check():
    vtk, _, _ = import_vtk()
    rw, _ = open_window(vtk, 16, 16)
    rw.Render()
    rw.WaitForCompletion()
    print("vtk_peer: VTK %s renders offscreen with %s (%s)" % (vtk.vtkVersion.GetVTKVersion(), rw.GetClassName(), gl_renderer(rw)))


def main(argv):
    try:
        if argv == ["--check"]:
            check()
        elif len(argv) == 2 and argv[0] == "--scene":
            try:
                with open(argv[1]) as fh:
                    scene = json.load(fh)
            except (OSError, ValueError) as e:
                raise PeerError("cannot read scene %s: %s" % (argv[1], e))
            render(scene)
        else:
            fail("usage: vtk_peer.py --scene SCENE.json | --check")
    except PeerError as e:
        fail(str(e))


if __name__ == "__main__":
    main(sys.argv[1:])
