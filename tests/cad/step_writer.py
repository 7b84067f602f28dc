"""Write STEP files the way a mechanical CAD program does, for the STEP-part tests: solids with
product names, named faces (ADVANCED_FACE names), face colours (sRGB) and layers, in mm or inch.

Written with OCC's XDE writer directly (build123d's export_step names solids but not faces)."""

from __future__ import annotations

from pathlib import Path


def write_step(path: Path, solids, unit: str = "MM") -> Path:
    """solids: [(name, build123d Solid, {face index: name}, {face index: "#rrggbb"}, {face index: layer})].
    unit: "MM" or "INCH" (OCC writes the coordinates in that unit and declares it)."""
    from OCP.IFSelect import IFSelect_ReturnStatus
    from OCP.Interface import Interface_Static
    from OCP.Quantity import Quantity_Color, Quantity_TOC_sRGB
    from OCP.STEPCAFControl import STEPCAFControl_Controller, STEPCAFControl_Writer
    from OCP.STEPControl import STEPControl_StepModelType
    from OCP.TCollection import TCollection_ExtendedString
    from OCP.TDataStd import TDataStd_Name
    from OCP.TDocStd import TDocStd_Document
    from OCP.XCAFApp import XCAFApp_Application
    from OCP.XCAFDoc import XCAFDoc_ColorType, XCAFDoc_DocumentTool

    doc = TDocStd_Document(TCollection_ExtendedString("XmlOcaf"))
    XCAFApp_Application.GetApplication_s().NewDocument(TCollection_ExtendedString("MDTV-XCAF"), doc)
    shapes = XCAFDoc_DocumentTool.ShapeTool_s(doc.Main())
    colours = XCAFDoc_DocumentTool.ColorTool_s(doc.Main())
    layers = XCAFDoc_DocumentTool.LayerTool_s(doc.Main())
    for name, solid, names, cols, lays in solids:
        if (names or cols or lays) and not solid.wrapped.Location().IsIdentity():
            solid = _baked(solid)  # XDE names sub-shapes of an unplaced shape only
        label = shapes.AddShape(solid.wrapped, False)
        TDataStd_Name.Set_s(label, TCollection_ExtendedString(name))
        faces = solid.faces()
        for k in sorted(set(names) | set(cols) | set(lays)):
            sub = shapes.AddSubShape(label, faces[k].wrapped)
            if k in names:
                TDataStd_Name.Set_s(sub, TCollection_ExtendedString(names[k]))
            if k in cols:
                rgb = [int(cols[k][i:i + 2], 16) / 255 for i in (1, 3, 5)]
                colours.SetColor(sub, Quantity_Color(*rgb, Quantity_TOC_sRGB), XCAFDoc_ColorType.XCAFDoc_ColorSurf)
            if k in lays:
                layers.SetLayer(sub, TCollection_ExtendedString(lays[k]))
    STEPCAFControl_Controller.Init_s()
    Interface_Static.SetCVal_s("write.step.unit", unit)
    Interface_Static.SetIVal_s("write.stepcaf.subshapes.name", 1)
    writer = STEPCAFControl_Writer()
    writer.SetNameMode(True)
    writer.SetColorMode(True)
    writer.SetLayerMode(True)
    writer.Transfer(doc, STEPControl_StepModelType.STEPControl_AsIs)
    assert writer.Write(str(path)) == IFSelect_ReturnStatus.IFSelect_RetDone
    Interface_Static.SetCVal_s("write.step.unit", "MM")  # a process-wide setting: leave it as found
    return path


def _baked(shape):
    """The shape with its location applied to the geometry (same face order)."""
    from build123d import Shape
    from OCP.BRepBuilderAPI import BRepBuilderAPI_Transform
    from OCP.TopLoc import TopLoc_Location

    w = shape.wrapped
    return Shape.cast(BRepBuilderAPI_Transform(w.Located(TopLoc_Location()), w.Location().Transformation(), True).Shape())
