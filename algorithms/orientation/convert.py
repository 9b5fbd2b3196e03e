"""orientation:convert - orientation files from one program's format to another's."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from toolbox.algorithm import Algorithm
from toolbox.feedback import Feedback
from toolbox.parameters import Crs, Enum, String
from toolbox.parameters.outputs import Output, OutputFile
from toolbox.registry import register

READ = ("auto", "opensfm", "opensfm_cameras", "orthority_interior", "orthority_exterior", "csv",
        "project", "metashape", "metashape_opk", "patb", "exif", "gcp")
WRITE = ("project", "orthority", "csv", "patb")
EXTENSIONS = {"project": (".yaml", ".yml"), "orthority": (".geojson", ".json", ".yaml", ".yml"),
              "csv": (".csv", ".txt"), "patb": (".ori", ".txt", ".dat"), "gcp": (".csv",)}


@register
class ConvertOrientations(Algorithm):
    """Read cameras and exterior orientations in one format, write them in another, and say what
    was understood (cameras, photos, CRS, angle conventions, frames).

    INPUT is one or more files (comma separated) or a folder (its orientation files; a folder of
    drone images only: their EXIF/XMP tags). FORMAT is detected per file unless given:
    ``opensfm`` (OpenSfM/ODM reconstruction.json: topocentric or ODM's UTM-offset frame, told
    apart by the shots' GPS positions, or FRAME), ``opensfm_cameras`` (cameras.json),
    ``orthority_interior`` (YAML), ``orthority_exterior`` (GeoJSON), ``csv`` (Orthority-style:
    any column order by header, quoted fields, x/y/z or latitude/longitude/altitude,
    omega/phi/kappa or roll/pitch/yaw, ``.prj`` sidecar), ``project`` (this product's YAML),
    ``metashape`` (camera XML: calibration, camera and chunk transforms), ``metashape_opk``
    (its Omega Phi Kappa text), ``patb`` (PAT-B: per photo ``id X0 Y0 Z0`` and the nine
    rotation-matrix elements in two records), ``exif`` (drone JPEG/TIFF: GNSS position, gimbal
    angles, focal length: approximate), ``gcp`` (ODM gcp_list.txt). Several inputs are merged
    (e.g. a camera YAML and an exterior GeoJSON); a camera or photo defined twice differently,
    or two CRSs, is an error. A project's photos get the images named after them (file stem)
    in IMAGES, else in the first input folder (or ODM's ``images/``) that holds some.

    Every orientation is converted to the product's omega-phi-kappa (R = Rx·Ry·Rz, camera x
    right, y up, z backward; OpenCV/OpenSfM/Metashape axes and angle-axis rotations converted,
    and the meridian convergence applied when going from a Cartesian frame to a map grid).
    ANGLE_UNIT is the unit of input angles when a file does not state it (a unit stated in the
    file that contradicts it, or mixed units, is an error). CRS is the target CRS (and the CRS
    of inputs that carry none); without it a reconstruction or geographic input goes to the
    UTM zone of its reference, as the summary says.

    FORMAT_OUT: ``project`` (YAML for the photo algorithms: cameras as ``model:`` entries, or
    the film fields of their pinhole part in a toolbox without camera models), ``orthority``
    (OUTPUT .geojson with ``<stem>_int_param.yaml`` beside it, or the interior .yaml alone),
    ``csv`` (filename,x,y,z,omega,phi,kappa,camera + ``.prj``), ``patb``. ANGLE_UNIT_OUT
    defaults to deg (project, csv); Orthority holds radians, PAT-B matrices. A ``gcp`` input
    writes the image-measurement CSV (point_id, photo, col_px, row_px) to OUTPUT and the ground
    points (id, X, Y, Z) beside it as ``<stem>_points.csv``.
    """

    id = "orientation:convert"
    display_name = "Convert orientation files"
    group = "Orientation"
    short_help = "Orientation files from/to OpenSfM, ODM, Orthority, Metashape, CSV, PAT-B, EXIF."
    parameters = [
        String("INPUT", "orientation file(s), comma separated, or a folder", paths=True),
        Enum("FORMAT", "input format", options=READ, default="auto"),
        Crs("CRS", "target CRS (and CRS of inputs that carry none)", optional=True),
        Enum("ANGLE_UNIT", "unit of input angles the files do not state",
             options=("rad", "deg", "gon"), optional=True),
        Enum("FRAME", "frame of a reconstruction.json", options=("auto", "topocentric",
                                                                  "utm_offset"), default="auto"),
        String("IMAGES", "folder of the photos' images, matched by file stem (FORMAT_OUT "
               "project; default: the input files' folders or ODM's images/)", optional=True,
               paths=True),
        Enum("FORMAT_OUT", "output format", options=WRITE, default="project"),
        Enum("ANGLE_UNIT_OUT", "unit of the angles written (default: the format's)",
             options=("rad", "deg", "gon"), optional=True),
        OutputFile("OUTPUT", "converted file", extensions=sorted({e for v in EXTENSIONS.values()
                                                                   for e in v})),
    ]
    outputs = [Output("SUMMARY", "what was read: format, cameras, photos, CRS, notes", "dict")]

    def check(self, params: dict[str, Any]) -> None:
        inputs = [s.strip() for s in str(params["INPUT"]).split(",") if s.strip()]
        if not inputs:
            raise self.fail("INPUT", "needs at least one file or folder")
        for item in inputs:
            try:
                exists = Path(item).exists()
            except OSError as exc:  # a name too long for the system...
                raise self.fail("INPUT", f"cannot use {item[:60]!r}: {exc.strerror}") from None
            if not exists:
                raise self.fail("INPUT", f"{item!r} does not exist")
        # OUTPUT itself against INPUT's files (a list, a folder's files): the runner's check
        out = Path(params["OUTPUT"]).resolve()
        beside = [out.with_suffix(".prj"), out.with_name(f"{out.stem}_points.csv"),
                  out.with_name(f"{out.stem.removesuffix('_ext_param')}_int_param.yaml")]
        for item in inputs:
            given = Path(item).resolve()
            files = {f.resolve() for f in (given.iterdir() if given.is_dir() else [given])}
            hit = next((b for b in beside if b in files), None)
            if hit is not None:
                raise self.fail("OUTPUT", f"would write {hit.name} beside it, which is an input; "
                                "an input is never overwritten: choose another name or folder")
        fmt = "gcp" if params["FORMAT"] == "gcp" else params["FORMAT_OUT"]
        if params["IMAGES"] is not None:
            if fmt != "project":
                raise self.fail("IMAGES", "applies to FORMAT_OUT project only (the other "
                                f"formats hold no image paths), got FORMAT_OUT {fmt}")
            if not Path(params["IMAGES"]).is_dir():
                raise self.fail("IMAGES", f"must be a folder of images, got "
                                f"{params['IMAGES']!r}")
        if params["FORMAT"] != "gcp" and out.suffix.lower() not in EXTENSIONS[fmt]:
            raise self.fail("OUTPUT", f"must end in {'/'.join(EXTENSIONS[fmt])} for FORMAT_OUT "
                            f"{fmt}, got {out.name!r}")

    def process(self, params: dict[str, Any], feedback: Feedback) -> dict[str, Any]:
        import json

        from toolbox.exchange import formats, odm_gcp

        inputs = [s.strip() for s in str(params["INPUT"]).split(",") if s.strip()]
        output = Path(params["OUTPUT"])
        left_out: list[str] = []
        files = formats.expand(inputs, left_out)
        kinds = [formats.detect(f) if params["FORMAT"] == "auto" else params["FORMAT"]
                 for f in files]
        if "gcp" in kinds:
            if len(files) != 1:
                self._gcp_alone()
            if output.suffix.lower() != ".csv":
                raise self.fail("OUTPUT", "must be a .csv (image measurements) for a gcp_list "
                                f"input, got {output.name!r}")
            control = odm_gcp.read_gcp_list(files[0], params["CRS"])
            for warning in control.warnings:  # a datum transformation coarser than control
                feedback.push_warning(warning)
            written = odm_gcp.write_control(control, output,
                                            output.with_name(f"{output.stem}_points.csv"))
            summary = {"format": "gcp", "source": str(files[0]),
                       "points": len(control.points), "measurements": len(control.measurements),
                       "crs": control.crs.name, "notes": control.notes}
        else:
            oset = formats.read_orientations(files, params["FORMAT"], params["CRS"],
                                             params["ANGLE_UNIT"], params["FRAME"])
            unit = params["ANGLE_UNIT_OUT"]
            written = formats.write_orientations(oset, params["FORMAT_OUT"], output, unit,
                                                 params["IMAGES"])
            oset.notes += left_out
            for note in oset.notes:  # what the output cannot hold: said loudly
                if "not carried over" in note:
                    feedback.push_warning(note)
            summary = oset.summary()
            summary["angle_unit_out"] = unit or {"project": "deg", "orthority": "rad",
                                                 "csv": "deg", "patb": "none (matrices)"}[
                                                     params["FORMAT_OUT"]]
        summary["written"] = [p.name for p in written]
        feedback.push_info(json.dumps(summary, indent=1, ensure_ascii=False))
        return {"OUTPUT": str(output), "SUMMARY": summary}

    def _gcp_alone(self) -> None:
        raise self.fail("INPUT", "a gcp_list (control points) converts alone, not merged with "
                        "orientation files")
