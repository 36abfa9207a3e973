#!/usr/bin/env python3
"""Checks that mmval's VTK outputs overlay in one frame, reading them with VTK's own
XML readers (python3-vtk9), as ParaView would.

Inputs: a fluid run's fields.vtr, the mask image the run and the video were made
from (grains dark), a tracker run's tracks.vtp and tracks.csv, and the pixel size.
The frame (docs/outputs.md): metres, x right, y up, origin at the image's
bottom-left corner; pixel (c, r) covers [c p, (c + 1) p] x [(rows - r - 1) p,
(rows - r) p]; a tracker position (x, y) in pixels has pixel (c, r)'s centre at
(c, r).

Checks, each printing the values compared:
  1. units: the field data "units" of fields.vtr names p [Pa], U [m/s],
     solid [1] and coordinates [m]; tracks.vtp names t [s]. Time: tracks.vtp's
     point array t equals tracks.csv's t_s.
  2. grains: the mask read by VTK's PNM reader, placed at pixel centres
     ((c + 1/2) p, (rows - r - 1/2) p), agrees pixel by pixel with the field's
     solid array probed there (cells_per_pixel = 1: one cell per pixel).
  3. bounds: the field spans the image (cols p x rows p) and every track point lies
     within the field's bounds.
  4. every track point lies in fluid: solid probed at the point (vtkProbeFilter)
     is 0, and the mask pixel under it is fluid.
  5. tracks.vtp's points are tracks.csv's pixel positions converted as above
     (to 1e-9 m: the CSV prints 4 decimals of a pixel).
With --particles-pvd (a particle run on the same mask) its series is checked as below,
and every particle position lies inside the field and in its fluid.

With --pvd instead (a time series: unsteady fields or particles), every dataset the
collection lists is read with VTK's reader for its type; its TimeValue equals the
collection's timestep (to 1e-12 relative: both carry 17 digits), the times increase,
units are present, and with --within every point lies inside the given box (m).
Exit status 0 when all hold, 1 otherwise, 2 when VTK is missing.
"""
import argparse
import csv
import os
import sys
import xml.etree.ElementTree as ET

try:
    from vtkmodules.vtkCommonCore import vtkPoints
    from vtkmodules.vtkCommonDataModel import vtkPolyData
    from vtkmodules.vtkFiltersCore import vtkProbeFilter
    from vtkmodules.vtkIOImage import vtkPNMReader
    from vtkmodules.vtkIOXML import vtkXMLPolyDataReader, vtkXMLRectilinearGridReader
except ImportError as e:  # the test treats this as a failure, not a skip
    print(f"overlay_check: VTK's Python modules are missing ({e}); install the Debian package python3-vtk9", file=sys.stderr)
    sys.exit(2)

failures = []


def check(ok, what):
    print(("ok    " if ok else "FAIL  ") + what)
    if not ok:
        failures.append(what)


def units_of(data):
    arr = data.GetFieldData().GetAbstractArray("units")
    return [] if arr is None else [arr.GetValue(i) for i in range(arr.GetNumberOfValues())]


def probe(source, xyz):
    """Values of source's arrays at the points xyz (VTK's probe filter)."""
    pts = vtkPoints()
    for p in xyz:
        pts.InsertNextPoint(*p)
    pd = vtkPolyData()
    pd.SetPoints(pts)
    f = vtkProbeFilter()
    f.SetInputData(pd)
    f.SetSourceData(source)
    f.Update()
    out = f.GetOutput()
    return out.GetPointData(), out.GetPointData().GetArray(f.GetValidPointMaskArrayName())


def check_series(pvd, within, field=None):
    """Checks a .pvd time series; with `field`, every point of every dataset (at z = 0)
    must also lie in its fluid (solid == 0)."""
    entries = ET.parse(pvd).getroot().findall("./Collection/DataSet")
    check(len(entries) >= 2, f"series: {len(entries)} datasets in {os.path.basename(pvd)}")
    last_t = None
    points, in_solid = 0, []
    for e in entries:
        name, t = e.get("file"), float(e.get("timestep"))
        reader = vtkXMLRectilinearGridReader() if name.endswith(".vtr") else vtkXMLPolyDataReader()
        reader.SetFileName(os.path.join(os.path.dirname(pvd), name))
        reader.Update()
        data = reader.GetOutput()
        tv = data.GetFieldData().GetArray("TimeValue")
        ok = tv is not None and abs(tv.GetValue(0) - t) <= 1e-12 * max(abs(t), 1e-300)
        check(ok and data.GetNumberOfPoints() > 0,
              f"series: {name}: {data.GetNumberOfPoints()} points, TimeValue {None if tv is None else tv.GetValue(0)} s, timestep {t} s")
        check(last_t is None or t > last_t, f"series: {name}: time {t} s after the previous {last_t} s")
        check("coordinates [m]" in units_of(data), f"series: {name}: units {units_of(data)}")
        last_t = t
        if within:
            b = data.GetBounds()
            inside = all(within[2 * k] <= b[2 * k] and b[2 * k + 1] <= within[2 * k + 1] for k in range(3))
            check(inside, f"series: {name}: bounds {tuple(round(v, 12) for v in b)} within {tuple(within)} m")
        if field is not None:
            xyz = [data.GetPoint(k)[:2] + (0.0,) for k in range(data.GetNumberOfPoints())]
            pd, valid = probe(field, xyz)
            solid = pd.GetArray("solid")
            in_solid += [(name, xyz[k]) for k in range(len(xyz)) if valid.GetValue(k) == 0 or solid.GetValue(k) != 0]
            points += len(xyz)
    if field is not None:
        where = "" if not in_solid else f"; first {in_solid[0]}"
        check(points > 0 and not in_solid, f"fluid: solid == 0 at {points - len(in_solid)} of {points} particle positions over the series{where}")
    return 1 if failures else 0


def correlation(a, b):
    n = len(a)
    ma, mb = sum(a) / n, sum(b) / n
    cov = sum((x - ma) * (y - mb) for x, y in zip(a, b))
    va, vb = sum((x - ma) ** 2 for x in a), sum((y - mb) ** 2 for y in b)
    return cov / (va * vb) ** 0.5 if va > 0 and vb > 0 else 0.0


def check_fields_3d(path, field, centres, solid_mask):
    """The 3D solution shares the plane frame: its x-y bounds are the field's, its solid at
    mid-depth is the mask at every pixel centre, and its velocity at mid-depth points the way
    the plane field's does (a y axis left pointing down would reverse v's correlation)."""
    r = vtkXMLRectilinearGridReader()
    r.SetFileName(path)
    r.Update()
    g = r.GetOutput()
    check("U [m/s]" in units_of(g) and "solid [1]" in units_of(g), f"fields-3d: units {units_of(g)}")
    b, b2 = g.GetBounds(), field.GetBounds()
    same = all(abs(b[k] - b2[k]) <= 1e-9 * max(b2[1], b2[3]) for k in range(4))
    check(same and b[5] > b[4] == 0.0, f"bounds: 3D field x {b[0]:.6g}..{b[1]:.6g}, y {b[2]:.6g}..{b[3]:.6g}, z {b[4]:.6g}..{b[5]:.6g} m; plane field x..y as its")
    mid = [(x, y, 0.5 * (b[4] + b[5])) for x, y, _ in centres]
    pd, valid = probe(g, mid)
    solid = pd.GetArray("solid")
    disagree = [k for k in range(len(mid)) if valid.GetValue(k) == 0 or (solid.GetValue(k) >= 0.5) != solid_mask[k]]
    check(not disagree, f"grains: mask and 3D solid (mid-depth) agree at {len(mid) - len(disagree)} of {len(mid)} pixel centres")
    u3 = pd.GetArray("U")
    pd2, _ = probe(field, centres)
    u2 = pd2.GetArray("U")
    fluid = [k for k in range(len(mid)) if not solid_mask[k]]
    for c, axis in ((0, "x"), (1, "y")):
        rho = correlation([u2.GetComponent(k, c) for k in fluid], [u3.GetComponent(k, c) for k in fluid])
        check(rho > 0.9, f"velocity: correlation of U_{axis} between the plane field and the 3D mid-depth over {len(fluid)} fluid pixels {rho:.4f} (> 0.9)")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--pvd", help="check a time series instead of the overlay")
    ap.add_argument("--within", type=float, nargs=6, help="with --pvd: x0 x1 y0 y1 z0 z1 (m) every point must lie in")
    ap.add_argument("--fields")
    ap.add_argument("--mask", help="PGM/PPM mask, grains dark")
    ap.add_argument("--tracks-vtp")
    ap.add_argument("--tracks-csv")
    ap.add_argument("--pixel-size-m", type=float)
    ap.add_argument("--fields-3d", help="overlay: the 3D solution on the same mask (fields-3d.vtr, one cell per pixel in the plane)")
    ap.add_argument("--particles-pvd", help="overlay: a particle run's series on the same mask, checked against the field too")
    a = ap.parse_args()
    if a.pvd:
        status = check_series(a.pvd, a.within)
        print(f"overlay_check: {len(failures)} failure(s)")
        return status
    if None in (a.fields, a.mask, a.tracks_vtp, a.tracks_csv, a.pixel_size_m):
        ap.error("the overlay needs --fields, --mask, --tracks-vtp, --tracks-csv and --pixel-size-m")
    p = a.pixel_size_m

    r = vtkXMLRectilinearGridReader()
    r.SetFileName(a.fields)
    r.Update()
    field = r.GetOutput()
    check(field.GetNumberOfCells() > 0, f"fields: {field.GetNumberOfCells()} cells read by vtkXMLRectilinearGridReader")
    cd = field.GetCellData()
    for name, comps in (("p", 1), ("U", 3), ("solid", 1)):
        arr = cd.GetArray(name)
        check(arr is not None and arr.GetNumberOfComponents() == comps, f"fields: cell array {name} with {comps} component(s)")
    units = units_of(field)
    for u in ("coordinates [m]", "p [Pa]", "U [m/s]", "solid [1]"):
        check(u in units, f"fields: units lists '{u}' (has {units})")

    t = vtkXMLPolyDataReader()
    t.SetFileName(a.tracks_vtp)
    t.Update()
    tracks = t.GetOutput()
    rows_csv = list(csv.DictReader(open(a.tracks_csv)))
    n = tracks.GetNumberOfPoints()
    check(n == len(rows_csv) and n > 0, f"tracks: {n} points in tracks.vtp, {len(rows_csv)} rows in tracks.csv")
    particles = {row["particle"] for row in rows_csv}
    check(tracks.GetNumberOfLines() == len(particles), f"tracks: {tracks.GetNumberOfLines()} polylines, {len(particles)} particles in tracks.csv")
    check("t [s]" in units_of(tracks), f"tracks: units lists 't [s]' (has {units_of(tracks)})")
    tarr = tracks.GetPointData().GetArray("t")
    check(tarr is not None, "tracks: point array t (time, s)")

    # The mask through VTK's image reader: row 0 of the file is the top, VTK puts it at the
    # largest j (its readers fill bottom-up), so point (i, j) is pixel (c = i, r = rows - 1 - j).
    m = vtkPNMReader()
    m.SetFileName(a.mask)
    m.Update()
    img = m.GetOutput()
    cols, rows, _ = img.GetDimensions()
    scal = img.GetPointData().GetScalars()
    xyz, solid_mask = [], []
    for j in range(rows):
        for i in range(cols):
            xyz.append(((i + 0.5) * p, (j + 0.5) * p, 0.0))
            solid_mask.append(scal.GetTuple1(j * cols + i) < 128)
    b = field.GetBounds()
    span = f"x {b[0]:.6g}..{b[1]:.6g} m, y {b[2]:.6g}..{b[3]:.6g} m"
    check(abs(b[0]) < 1e-12 and abs(b[2]) < 1e-12 and abs(b[1] - cols * p) < 1e-9 * cols * p and abs(b[3] - rows * p) < 1e-9 * rows * p,
          f"bounds: field spans {span}; the image {cols} x {rows} px of {p:g} m spans x 0..{cols * p:.6g} m, y 0..{rows * p:.6g} m")
    pd, valid = probe(field, xyz)
    solid_at = pd.GetArray("solid")
    disagree = [k for k in range(len(xyz)) if valid.GetValue(k) == 0 or (solid_at.GetValue(k) >= 0.5) != solid_mask[k]]
    where = "" if not disagree else f"; first at pixel centre {xyz[disagree[0]]}, mask solid {solid_mask[disagree[0]]}, field solid {solid_at.GetValue(disagree[0])}"
    check(not disagree, f"grains: mask and field solid agree at {len(xyz) - len(disagree)} of {len(xyz)} pixel centres{where}")

    # Tracks against the field: inside its bounds and in fluid.
    tb = tracks.GetBounds()
    check(tb[0] >= b[0] and tb[1] <= b[1] and tb[2] >= b[2] and tb[3] <= b[3],
          f"bounds: tracks x {tb[0]:.6g}..{tb[1]:.6g} m, y {tb[2]:.6g}..{tb[3]:.6g} m within the field's {span}")
    txyz = [tracks.GetPoint(k) for k in range(n)]
    pd, valid = probe(field, txyz)
    solid_at = pd.GetArray("solid")
    in_solid = [k for k in range(n) if valid.GetValue(k) == 0 or solid_at.GetValue(k) != 0]
    where = "" if not in_solid else f"; first {txyz[in_solid[0]]} with solid {solid_at.GetValue(in_solid[0])}"
    check(not in_solid, f"fluid: solid == 0 at {n - len(in_solid)} of {n} track points{where}")
    mask_solid = 0
    for x, y, _ in txyz:
        c, jr = int(x / p), int(y / p)  # VTK image index j counts from the bottom
        mask_solid += solid_mask[jr * cols + c]
    check(mask_solid == 0, f"fluid: {mask_solid} track points on grain pixels of the mask")

    # tracks.vtp against tracks.csv (the same rows in the same order: particle, then frame).
    worst, worst_t = 0.0, 0.0
    for k, row in enumerate(rows_csv[:n]):
        X = (float(row["x"]) + 0.5) * p
        Y = (rows - float(row["y"]) - 0.5) * p
        worst = max(worst, abs(txyz[k][0] - X), abs(txyz[k][1] - Y))
        if tarr is not None:
            worst_t = max(worst_t, abs(tarr.GetValue(k) - float(row["t_s"])))
    check(worst <= 1e-9, f"tracks: largest difference from tracks.csv converted to the frame {worst:.3g} m (tolerance 1e-9 m, 5e-4 px)")
    check(worst_t <= 1e-6, f"time: largest difference of t from tracks.csv's t_s {worst_t:.3g} s (tolerance 1e-6 s, the CSV's 6 digits)")

    if a.fields_3d:
        check_fields_3d(a.fields_3d, field, xyz, solid_mask)

    if a.particles_pvd:
        # Particles of a run on the same mask: inside the field's plane (z from the bottom plate up) and in fluid.
        check_series(a.particles_pvd, [b[0], b[1], b[2], b[3], 0.0, float("inf")], field)

    print(f"overlay_check: {len(failures)} failure(s)")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
