import vtk
def coords(t,n):
    ug = vtk.vtkUnstructuredGrid(); pts = vtk.vtkPoints(); pts.SetNumberOfPoints(n)
    for i in range(n): pts.SetPoint(i, i, 0, 0)
    ug.SetPoints(pts); ug.InsertNextCell(t, n, list(range(n)))
    c = ug.GetCell(0)
    p = c.GetParametricCoords()
    return [tuple(p[3*i+j] for j in range(3)) for i in range(c.GetNumberOfPoints())]
out=["// Generated from VTK 9.7's GetParametricCoords (scripts/gen_higher_order_tables.py with the VTK wheel): each node's",
     "// position on the cell's integer lattice (parametric coordinates times the degree).",
     "// (VTK type, node count, degree, lattice positions)",
     "pub(super) const NODE_LATTICES: &[(u8, usize, u8, &[[u8; 3]])] = &["]
specs=[(24,10,2),(25,20,2),(26,15,2),(29,27,2),(31,12,2),(32,18,2),(33,24,2)]
for p in range(1,5):
    specs += [(71,(p+1)*(p+2)*(p+3)//6,p),(72,(p+1)**3,p),(73,(p+1)**2*(p+2)//2,p)]
for t,n,p in specs:
    cs=coords(t,n); assert len(cs)==n,(t,n,len(cs))
    lat=[]
    for c in cs:
        l=[round(x*p) for x in c]
        assert all(abs(x*p-round(x*p))<1e-6 for x in c),(t,n,c)
        lat.append("[%d, %d, %d]"%tuple(l))
    out.append("    (%d, %d, %d, &[%s]),"%(t,n,p,", ".join(lat)))
out.append("];")
open("/work/wt/split/src/mesh/higher_order_tables.rs","w").write("\n".join(out)+"\n")
