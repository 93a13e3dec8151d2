"""Writes tests/fixtures/polyhedra.* with VTK's own writers: two stacked
pentagonal prisms and two unit cubes beside them, all as polyhedra (42)."""
import vtk
ring = [(0, 0), (1, 0), (1, 1), (0.5, 1.5), (0, 1)]
pts = vtk.vtkPoints()
for z in range(3):
    for p in ring:
        pts.InsertNextPoint(p[0], p[1], z)
    pts.InsertNextPoint(2, 0, z)
    pts.InsertNextPoint(2, 1, z)
at = lambda i, z: i + 7 * z
ug = vtk.vtkUnstructuredGrid()
ug.SetPoints(pts)
def add(faces):
    stream = [len(faces)]
    for f in faces:
        stream += [len(f)] + f
    ids = vtk.vtkIdList()
    for x in stream:
        ids.InsertNextId(x)
    ug.InsertNextCell(42, ids)
for z in range(2):
    faces = [[at(i, z) for i in range(5)], [at(i, z + 1) for i in reversed(range(5))]]
    for i in range(5):
        j = (i + 1) % 5
        faces.append([at(i, z), at(j, z), at(j, z + 1), at(i, z + 1)])
    add(faces)
    q = [at(1, z), at(5, z), at(6, z), at(2, z)]
    r = [at(1, z + 1), at(5, z + 1), at(6, z + 1), at(2, z + 1)]
    faces = [q, list(reversed(r))]
    for i in range(4):
        j = (i + 1) % 4
        faces.append([q[i], q[j], r[j], r[i]])
    add(faces)
s = vtk.vtkDoubleArray()
s.SetName("s")
for i in range(pts.GetNumberOfPoints()):
    x, y, z = pts.GetPoint(i)
    s.InsertNextValue(x + 2 * y + 3 * z)
ug.GetPointData().AddArray(s)
for mode, name in [("ascii", "polyhedra_ascii.vtu"), ("appended", "polyhedra_appended.vtu")]:
    w = vtk.vtkXMLUnstructuredGridWriter()
    w.SetInputData(ug)
    w.SetFileName(name)
    w.SetDataModeToAscii() if mode == "ascii" else w.SetDataModeToAppended()
    w.Write()
for version, name in [(42, "polyhedra_42.vtk"), (51, "polyhedra_51.vtk")]:
    w = vtk.vtkUnstructuredGridWriter()
    w.SetInputData(ug)
    w.SetFileName(name)
    w.SetFileVersion(version)
    w.Write()
t = vtk.vtkDataSetTriangleFilter()
t.SetInputData(ug)
t.Update()
print("VTK's vtkDataSetTriangleFilter:", t.GetOutput().GetNumberOfCells(), "tets")
