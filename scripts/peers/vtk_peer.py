#!/usr/bin/env python3
"""VTK as a peer of volbench (`volbench suite --peers vtk`).

volbench writes a scene file (JSON: the dataset -- volbench's export as a
legacy VTK file, or a user's original file for VTK's own reader, with the
scalar array, its association and cell-data treatment --, the renderer to use, image size, one camera per warm-up and timed frame plus the
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
VERSION = 2

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


# A user's original file: the format key volbench sends, and VTK's reader.
ORIGINAL_READERS = {
    "vtk-legacy": "vtkDataSetReader",
    "vtu": "vtkXMLUnstructuredGridReader",
    "pvtu": "vtkXMLPUnstructuredGridReader",
    "vti": "vtkXMLImageDataReader",
    "nrrd": "vtkNrrdReader",
    "nifti": "vtkNIFTIImageReader",
    "metaimage": "vtkMetaImageReader",
    "plot3d": "vtkMultiBlockPLOT3DReader",
}


def read_file(vtk, dataset, path, fmt):
    """The data as VTK's own reader gives it (a user's original file), or
    volbench's export."""
    if fmt == "vtk-legacy-unstructured-grid":
        reader = vtk.vtkUnstructuredGridReader()
    elif fmt == "vtk-legacy-structured-points":
        reader = vtk.vtkStructuredPointsReader()
    elif fmt in ORIGINAL_READERS:
        reader = getattr(vtk, ORIGINAL_READERS[fmt])()
    else:
        raise PeerError("scene: unknown dataset format '%s'" % fmt)
    if fmt == "plot3d":
        reader.SetXYZFileName(path)
        reader.SetQFileName(need(dataset, "solution_file", str, "dataset"))
        reader.AutoDetectFormatOn()
    else:
        reader.SetFileName(path)
    if fmt == "vtk-legacy":
        # Every array, not only the first of each attribute kind.
        reader.ReadAllScalarsOn()
        reader.ReadAllVectorsOn()
        reader.ReadAllFieldsOn()
    reader.Update()
    data = reader.GetOutput()
    if fmt == "plot3d":
        data = data.GetBlock(0) if data is not None and data.GetNumberOfBlocks() > 0 else None
        if data is not None:
            plot3d_scalar(vtk, data)
    if fmt == "nifti":
        data = nifti_as_volbench_places_it(vtk, reader, data)
    return data


def plot3d_scalar(vtk, data):
    """volbench's PLOT3D scalar: the density, or the velocity magnitude
    (|momentum| / density) when the density is constant over the grid."""
    from vtkmodules.util import numpy_support
    import numpy
    pd = data.GetPointData()
    rho = pd.GetArray("Density")
    mom = pd.GetArray("Momentum")
    if rho is None or mom is None:
        raise PeerError("PLOT3D: VTK's reader gave no Density or Momentum")
    r = numpy_support.vtk_to_numpy(rho).astype(numpy.float64)
    if numpy.all(r == r[0]):
        m = numpy_support.vtk_to_numpy(mom).astype(numpy.float64)
        s = numpy.sqrt((m * m).sum(axis=1)) / r
    else:
        s = r
    a = numpy_support.numpy_to_vtk(numpy.ascontiguousarray(s), deep=1)
    a.SetName("volbench-plot3d-scalar")
    pd.AddArray(a)


def nifti_as_volbench_places_it(vtk, reader, data):
    """NIfTI as volbench reads it: scl_slope / scl_inter applied, the grid
    placed axis-aligned at the transform's translation (sform, else qform),
    voxel size the sform's column lengths (else pixdim). VTK's reader keeps
    the transform apart and leaves the scaling to the caller."""
    slope, inter = reader.GetRescaleSlope(), reader.GetRescaleIntercept()
    out = vtk.vtkImageData()
    out.DeepCopy(data)
    if slope != 0.0 and (slope != 1.0 or inter != 0.0):
        from vtkmodules.util import numpy_support
        import numpy
        arr = out.GetPointData().GetScalars()
        v = numpy_support.vtk_to_numpy(arr).astype(numpy.float64) * slope + inter
        a = numpy_support.numpy_to_vtk(numpy.ascontiguousarray(v.astype(numpy.float32)), deep=1)
        a.SetName(arr.GetName() or "scalars")
        out.GetPointData().SetScalars(a)
    m = None
    if reader.GetSFormMatrix() is not None and reader.GetNIFTIHeader().GetSFormCode() > 0:
        m = reader.GetSFormMatrix()
        out.SetSpacing(*[math.sqrt(sum(m.GetElement(r, c) ** 2 for r in range(3))) for c in range(3)])
    elif reader.GetQFormMatrix() is not None and reader.GetNIFTIHeader().GetQFormCode() > 0:
        m = reader.GetQFormMatrix()
    # VTK's reader may flip the rows (its own convention); volbench keeps the file's order.
    if m is not None:
        out.SetOrigin(m.GetElement(0, 3), m.GetElement(1, 3), m.GetElement(2, 3))
    else:
        out.SetOrigin(0.0, 0.0, 0.0)
    return out


def pick_array(arrays, want, one_component_default, where):
    """The array named `want`, else the active scalars, else the first array
    (of one component when `one_component_default`): volbench's rule."""
    if want is not None:
        a = arrays.GetArray(want)
        if a is None:
            raise PeerError("%s: VTK read no %s array named '%s'" % (where, arrays_kind(arrays), want))
        return a
    if arrays.GetScalars() is not None:
        return arrays.GetScalars()
    for i in range(arrays.GetNumberOfArrays()):
        a = arrays.GetArray(i)
        if a is not None and (not one_component_default or a.GetNumberOfComponents() == 1):
            return a
    raise PeerError("%s: VTK read no %s array to use as the scalar" % (where, arrays_kind(arrays)))


def arrays_kind(arrays):
    return "cell" if arrays.IsA("vtkCellData") else "point"


def as_scalar(vtk, array):
    """One component as it is; several by magnitude (volbench's rule), as a
    new double array."""
    if array.GetNumberOfComponents() == 1:
        return array
    from vtkmodules.util import numpy_support
    import numpy
    v = numpy_support.vtk_to_numpy(array).astype(numpy.float64)
    m = numpy.sqrt((v * v).sum(axis=1))
    a = numpy_support.numpy_to_vtk(numpy.ascontiguousarray(m), deep=1)
    a.SetName((array.GetName() or "array") + "-magnitude")
    return a


def read_data(vtk, dataset):
    path = need(dataset, "file", str, "dataset")
    fmt = need(dataset, "format", str, "dataset")
    kind = need(dataset, "kind", str, "dataset")
    if not os.path.isfile(path):
        raise PeerError("scene: dataset file %s does not exist" % path)
    scalar = dataset.get("scalar") or {}
    if not isinstance(scalar, dict):
        raise PeerError("scene: 'scalar' in dataset must be an object")
    want = scalar.get("array")
    if want is not None and not isinstance(want, str):
        raise PeerError("scene: dataset.scalar.array must be a string or null")
    association = scalar.get("association", "point")
    cell_data = scalar.get("cell_data")
    if association not in ("point", "cell") or (association == "cell" and cell_data not in ("constant", "average")):
        raise PeerError("scene: dataset.scalar: association '%s' with cell_data '%s' (point, or cell with constant or average)" % (association, cell_data))
    data = read_file(vtk, dataset, path, fmt)
    if data is None or data.GetNumberOfPoints() == 0:
        raise PeerError("%s: VTK's reader read no points" % path)
    is_mesh = kind == "tet-mesh"
    if is_mesh and not (data.IsA("vtkUnstructuredGrid") or data.IsA("vtkStructuredGrid")):
        raise PeerError("%s: VTK read a %s, not an unstructured grid" % (path, data.GetClassName()))
    if not is_mesh and not data.IsA("vtkImageData"):
        raise PeerError("%s: VTK read a %s, not image data" % (path, data.GetClassName()))
    if fmt == "plot3d" and want is None:
        want = "volbench-plot3d-scalar"
    # volbench's default in .vtu / .pvtu: the first point array of any width;
    # in legacy files and .vti: the first one-component one.
    one = fmt not in ("vtu", "pvtu")
    if association == "point":
        chosen = as_scalar(vtk, pick_array(data.GetPointData(), want, one, path))
        if chosen.GetName() is None:
            chosen.SetName("volbench-scalar")
        if chosen is not data.GetPointData().GetArray(chosen.GetName()):
            data.GetPointData().AddArray(chosen)
        data.GetPointData().SetActiveScalars(chosen.GetName())
    else:
        chosen = as_scalar(vtk, pick_array(data.GetCellData(), want, one, path))
        if chosen.GetName() is None:
            chosen.SetName("volbench-scalar")
        if chosen is not data.GetCellData().GetArray(chosen.GetName()):
            data.GetCellData().AddArray(chosen)
        data.GetCellData().SetActiveScalars(chosen.GetName())
        if cell_data == "average":
            c2p = vtk.vtkCellDataToPointData()
            c2p.SetInputData(data)
            c2p.PassCellDataOff()
            c2p.Update()
            data = c2p.GetOutput()
            data.GetPointData().SetActiveScalars(chosen.GetName())
            association = "point"
    if is_mesh and not all_tetrahedra(vtk, data):
        # VTK's own filter: every 3-D cell into tetrahedra (lower-dimensional
        # cells dropped, as volbench skips them).
        tri = vtk.vtkDataSetTriangleFilter()
        tri.SetInputData(data)
        tri.TetrahedraOnlyOn()
        tri.Update()
        data = tri.GetOutput()
    if is_mesh and data.GetNumberOfCells() == 0:
        raise PeerError("%s: no tetrahedra after VTK's vtkDataSetTriangleFilter" % path)
    return data, association


def all_tetrahedra(vtk, data):
    if not data.IsA("vtkUnstructuredGrid"):
        return False
    types = vtk.vtkCellTypes()
    data.GetCellTypes(types)
    return types.GetNumberOfTypes() == 1 and types.GetCellType(0) == vtk.VTK_TETRA


def build_mapper(vtk, renderer, data, scene, association="point"):
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
    if association == "cell":
        m.SetScalarModeToUseCellData()
    else:
        m.SetScalarModeToUsePointData()
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
    data, association = read_data(vtk, dataset)
    load_ms = (time.perf_counter() - t0) * 1e3
    t0 = time.perf_counter()
    rw, ren = open_window(vtk, width, height)
    volume = vtk.vtkVolume()
    volume.SetMapper(build_mapper(vtk, renderer, data, scene, association))
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
