"""ortho:photo - orthorectify one frame photo on a DEM (differential rectification)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from toolbox.algorithm import Algorithm
from toolbox.errors import InputDataError, ParameterError
from toolbox.feedback import Feedback
from toolbox.parameters import (
    Boolean,
    Crs,
    Enum,
    ExtentParameter,
    File,
    Number,
    Output,
    OutputFile,
    OutputRaster,
    RasterLayer,
    String,
)
from toolbox.registry import register
from toolbox.ui.execution import executor_of, scheduler_parameter
from toolbox.ui.photogrammetry import (  # duplicate-ok: the same groups as ortho:batch
    dem_parameters,
    ortho_method_parameters,
    project_parameter,
    rpc_gcp_parameters,
)


@register
class OrthoPhoto(Algorithm):
    """Orthophoto of one frame photo: differential rectification on a DEM (indirect method,
    domain brief section 15; thesis par. 2.6.5 and 3.8).

    For every output cell centre the height comes from the DEM (bilinear between DEM cell
    centres, the edge value held across the DEM's outer half cell as gdalwarp does, so orthos
    of adjacent DEM tiles meet without a gap; a DEM in another CRS is reprojected on the fly
    with pyproj), the collinearity equations (brief section 4) project the point into the
    photo, radial distortion, the principal point and the pixel -> fiducial transform of the
    interior orientation are applied, and the photo is resampled there (nearest, bilinear,
    cubic, lanczos by OpenCV; quadratic, the thesis' Z-Map choice, by Dodgson's interpolating
    quadratic kernel).
    Without distortion the projection is exact at every cell (the collinearity equations are a
    3 x 4 projective matrix on (X, Y, Z, 1)); with distortion it is evaluated exactly at the
    corners of MAP_BLOCK x MAP_BLOCK cell blocks and blended inside only where the blend is
    provably within MAP_TOLERANCE photo pixels (default 0.05 px; bound = Lipschitz constant of
    the distortion x condition of the pixel transform x diagonal of the block's pixel box,
    checked per block; other blocks are computed exactly; MAP_BLOCK 64 as the thesis'
    "tasselli", the fastest measured). The work is streamed by output windows (local threads,
    or a Dask cluster with SCHEDULER): memory stays bounded for a 16644 x 16644 scan. The
    ortho is in the orientation's CRS, or in CRS when given with PROJECT: the cell centres then
    go to the orientation's CRS through a pyproj lattice checked to 1/1000 of a cell and are
    projected point by point (not with OCCLUSION or INCIDENCE). The DEM may be in any CRS.

    The orientation comes from PROJECT (an orientation project; PHOTO names the photo, default
    the one whose image file or id matches INPUT; without INPUT, PHOTO's image in PROJECT is
    orthorectified) or from CAMERA (a camera YAML as in a
    project's ``cameras`` list; the pixel transform from its pixel and image size) with
    EXTERIOR = "X0,Y0,Z0,omega,phi,kappa" in ANGLE_UNIT and CRS. A camera may be a model
    (``model:`` pinhole, Brown, OpenCV or fisheye; README "Camera models"): its cells are
    mapped through the model's projection, exactly at every cell, and remapped by OpenCV.

    An INPUT with RPCs (a satellite image: GDAL reads them from its tags, ``.RPB`` or
    ``_RPC.TXT``), given without PROJECT or CAMERA, is orthorectified through its RPC camera:
    every cell's DEM height and position projected exactly by the RPCs, in CRS (default the
    DEM's), the default extent the image outline on the DEM's lowest and highest heights, the
    default cell its GSD. CONTROL (id, X, Y, Z in CRS, heights in the RPCs' datum) with
    MEASUREMENTS (point_id, photo, col_px, row_px) refine the RPCs by an image-space bias
    (BIAS: shift from 1 GCP, affine from 3; auto = affine from 4), reported with the RMS before
    and after.

    HEIGHTS is the height datum of the orientation (``ellipsoidal`` or a vertical CRS such as
    EPSG:3855; default the project CRS's vertical part; an RPC camera's is ellipsoidal). When the
    DEM's CRS names another vertical datum, its heights are converted once with pyproj (a
    missing PROJ grid is an error naming it); same datum or one side unstated: used as they
    are. The report's ``heights`` says which.

    Defaults as the thesis' software proposes: CELL_SIZE = the photo's ground sample distance
    at the mean terrain height of its footprint (2 significant digits); EXTENT = the footprint
    on the DEM (cut to the DEM where an oblique photo's rays run off it or over the horizon);
    grid edges on multiples of the cell (or on the lattice of TEMPLATE), so orthos of one block
    share a grid. DEM_FACTOR > 1 projects on a coarser DEM (the mean of
    factor x factor cells), as Z-Map's resampling factor.

    OCCLUSION=true is the true-ortho step: each cell's line of sight to the projection centre
    is walked over the DEM/DSM; cells hidden by a higher object are left empty (no "double
    mapping") and written to OCCLUSION_MASK (1 hidden, 0 seen, 255 no height). INCIDENCE
    writes the angle (degrees) between the ray and the surface normal (as GRASS
    i.ortho.rectify): large values show where the ortho is smeared.

    Cells without a DEM height or outside the photo get alpha 0 (OUTSIDE=alpha) or NODATA;
    they are counted, never invented. The REPORT (JSON) lists GSD, extent, fractions outside
    the DEM/photo, the hidden fraction, the largest relief displacement corrected (metres and
    photo pixels; rho·|Z - Zmean|/(Z0 - Z)) and, given MAP_SCALE, the planimetric accuracy the
    seeds' rule expects (RMS ±0.3 mm to ±0.5 mm at the map scale, par. 2.6.6).
    """

    crs_labels_inputs = False  # CRS is the ortho's (the DEM's is its own or the project's)

    id = "ortho:photo"
    display_name = "Orthophoto of one photo"
    group = "Orthophoto"
    short_help = "Orthorectify a frame photo on a DEM (collinearity, optional true-ortho mask)."
    parameters = [
        RasterLayer("INPUT", "the photo (any GDAL raster, 1-4 bands, 8/16 bit; default with "
                    "PROJECT and PHOTO: the photo's image in the project)", role="photo",
                    optional=True),
        project_parameter(optional=True),
        String("PHOTO", "photo id in PROJECT (default: the photo whose image or id matches "
               "INPUT)", optional=True),
        File("CAMERA", "camera YAML (instead of PROJECT)", extensions=[".yaml", ".yml"],
             optional=True),
        String("EXTERIOR", "X0,Y0,Z0,omega,phi,kappa (with CAMERA)", optional=True),
        String("PIXEL_TO_IMAGE", "with CAMERA: the Pixel->Fiducial matrix, 6 or 8 numbers row "
               "by row (orientation:interior's); default: from the camera's pixel size",
               optional=True),
        Enum("ANGLE_UNIT", "unit of omega, phi, kappa in EXTERIOR", options=("rad", "deg", "gon"),
             default="rad"),
        Crs("CRS", "the ortho's CRS (default: the project's); with CAMERA also EXTERIOR's",
            optional=True),
        *dem_parameters("terrain heights (or a DSM for true orthos), any CRS"),
        String("HEIGHTS", "height datum of the orientation: 'ellipsoidal' or a vertical CRS "
               "(EPSG:3855...); default the project CRS's vertical part", optional=True),
        Number("CELL_SIZE", "ground cell size, CRS units (default: the photo's GSD)",
               optional=True, min_value=0, min_exclusive=True),
        ExtentParameter("EXTENT", "output extent (default: the footprint on the DEM)",
                        optional=True),
        RasterLayer("TEMPLATE", "align the grid to this raster's lattice (and cell size)",
                    optional=True),
        *ortho_method_parameters(),
        Boolean("OCCLUSION", "true ortho: leave cells hidden from the camera empty",
                default=False),
        Boolean("COG", "write a Cloud Optimized GeoTIFF", default=False),
        Boolean("OVERVIEWS", "build internal overviews", default=True),
        scheduler_parameter("the windows"),
        Number("MAP_SCALE", "map scale denominator for the expected accuracy (e.g. 5000)",
               optional=True, min_value=1),
        *rpc_gcp_parameters(),
        OutputRaster("OUTPUT", "orthophoto GeoTIFF"),
        OutputRaster("OCCLUSION_MASK", "occlusion mask (needs OCCLUSION)", optional=True),
        OutputRaster("INCIDENCE", "incidence angle raster, degrees", optional=True),
        OutputFile("REPORT", "JSON report", extensions=[".json"], optional=True),
    ]
    outputs = [Output("STATISTICS", "the per-photo report", "dict")]

    def check(self, params: dict[str, Any]) -> None:
        from toolbox.ortho.rpc import has_rpc

        if params["INPUT"] is None:
            params["INPUT"] = project_image(params)
        if (params["CONTROL"] is None) != (params["MEASUREMENTS"] is None):
            raise self.fail("CONTROL", "and MEASUREMENTS go together (the GCPs of an RPC image)")
        if params["PROJECT"] is None and params["CAMERA"] is None:
            if not has_rpc(params["INPUT"].path):
                raise self.fail("PROJECT", "give either PROJECT (with PHOTO) or CAMERA with "
                                "EXTERIOR (or an INPUT with RPCs)")
            for name in ("OCCLUSION", "OCCLUSION_MASK", "INCIDENCE", "EXTERIOR"):
                if params[name]:
                    raise self.fail(name, "does not apply to an RPC image")
            return
        if params["CONTROL"] is not None:
            raise self.fail("CONTROL", "applies to an RPC image only (INPUT with RPCs, no "
                            "PROJECT or CAMERA)")
        if params["PROJECT"] is not None and params["CAMERA"] is not None:
            raise self.fail("PROJECT", "give either PROJECT (with PHOTO) or CAMERA with EXTERIOR")
        if params["CAMERA"] is not None and params["EXTERIOR"] is None:
            raise self.fail("EXTERIOR", "is required with CAMERA (X0,Y0,Z0,omega,phi,kappa)")
        if params["PIXEL_TO_IMAGE"] is not None and params["CAMERA"] is None:
            raise self.fail("PIXEL_TO_IMAGE", "applies with CAMERA only (a project holds its "
                            "photos' interior orientations)")
        if params["OCCLUSION_MASK"] is not None and not params["OCCLUSION"]:
            raise self.fail("OCCLUSION_MASK", "needs OCCLUSION=true")

    def process(self, params: dict[str, Any], feedback: Feedback) -> dict[str, Any]:
        from toolbox.ortho.plan import check_geometry, plan_photo, tilt_warning
        from toolbox.ortho.run import OrthoOptions, orthorectify
        from toolbox.photogrammetry.photo import fit_image_size
        from toolbox.photogrammetry.tables import write_json

        executor = executor_of(params)  # a bad address is refused before any work
        if params["PROJECT"] is None and params["CAMERA"] is None:
            report = rpc_ortho(params, feedback, executor)
            if params["REPORT"] is not None:
                write_json(params["REPORT"], {"algorithm": self.id, "photos": [report]})
            return {"OUTPUT": params["OUTPUT"], "OCCLUSION_MASK": None, "INCIDENCE": None,
                    "REPORT": params["REPORT"], "STATISTICS": report}
        photo, crs, output_crs = oriented_photo(params)
        info = params["INPUT"]
        photo = fit_image_size(photo, info.width, info.height, info.path)
        if crs is None and output_crs is None and params["DEM"].crs is not None:
            from toolbox.io.crs import crs_label

            crs = params["DEM"].crs  # else the ortho would have no CRS at all
            feedback.push_warning(f"the orientation names no CRS: its coordinates are taken to "
                                  f"be in the DEM's, {crs_label(crs)}, and the ortho is written "
                                  "in it (give CRS to say otherwise)")
        check_geometry(photo)  # a camera looking away is an error, not a tilt warning
        warning = tilt_warning(photo)
        if warning:
            feedback.push_warning(warning)
        out_crs = output_crs or crs
        if out_crs is not crs and (params["OCCLUSION"] or params["INCIDENCE"] is not None):
            from toolbox.io.crs import one_crs

            eo = photo.require_exterior()  # one CRS with two definitions: the same place
            if not one_crs(crs, out_crs, (eo.x0, eo.y0, eo.x0, eo.y0)):
                raise ParameterError("CRS", "differs from the orientation's: OCCLUSION and "
                                     "INCIDENCE need the ortho in the orientation's CRS")
        from toolbox.ortho.vertical import dem_in_photo_datum

        with dem_in_photo_datum(params["DEM"], params["BAND"], params["HEIGHTS"], crs,
                                feedback, executor, params["OUTPUT"]) as (dem, band, heights):
            plan = plan_photo(photo, dem, crs, band, *grid_choice(params, out_crs),
                              output_crs=out_crs)
            options = OrthoOptions(
                resampling=params["RESAMPLING"], outside=params["OUTSIDE"],
                nodata=params["NODATA"], block=params["MAP_BLOCK"],
                tolerance_px=params["MAP_TOLERANCE"], dem_factor=params["DEM_FACTOR"], band=band,
                occlusion=params["OCCLUSION"], overviews=params["OVERVIEWS"], cog=params["COG"])
            report = orthorectify(photo, params["INPUT"], dem, plan.grid, params["OUTPUT"],
                                  options, plan.surface, plan.mean_height,
                                  params["OCCLUSION_MASK"], params["INCIDENCE"],
                                  params["MAP_SCALE"], feedback, executor=executor)
        report["footprint"] = [list(p) for p in plan.footprint.exterior.coords]
        report["heights"] = heights.as_dict()
        if params["REPORT"] is not None:
            write_json(params["REPORT"], {"algorithm": self.id, "photos": [report]})
        return {"OUTPUT": params["OUTPUT"], "OCCLUSION_MASK": params["OCCLUSION_MASK"],
                "INCIDENCE": params["INCIDENCE"], "REPORT": params["REPORT"],
                "STATISTICS": report}


def project_image(params: dict[str, Any]) -> Any:
    """INPUT when not given: the image PROJECT records for PHOTO (refused without them, or
    when the project has no image for it, or when an output would replace it)."""
    from toolbox.io.raster import open_raster_info
    from toolbox.photogrammetry.tables import load_project_parameter
    from toolbox.stereo.epipolar import photo_image

    if params["PROJECT"] is None or params["PHOTO"] is None:
        raise ParameterError("INPUT", "is required (the photo's image) unless PROJECT and PHOTO "
                             "name a photo whose image the project records")
    photo = load_project_parameter(params["PROJECT"]).photo(params["PHOTO"])
    info = open_raster_info(photo_image(photo, None, "INPUT"), "INPUT", "photo")
    for name in ("OUTPUT", "OCCLUSION_MASK", "INCIDENCE"):
        if params[name] is not None and Path(params[name]).resolve() == info.path.resolve():
            raise ParameterError(name, f"'{params[name]}' is the image of photo "
                                 f"{params['PHOTO']!r} (INPUT): it would be replaced")
    return info


def rpc_ortho(params: dict[str, Any], feedback: Feedback,
              executor: Any = None) -> dict[str, Any]:
    """The ortho of an INPUT with RPCs (GDAL's: tags, .RPB, _RPC.TXT): the grid in CRS (default
    the DEM's), the optional GCP bias refinement, the DEM in the RPCs' ellipsoidal heights
    (or HEIGHTS)."""

    from toolbox.cameras import read_rpc
    from toolbox.ortho.rpc import rpc_crs, rpc_orthorectify, rpc_plan
    from toolbox.ortho.rpc_block import refine_from_gcps
    from toolbox.ortho.run import OrthoOptions
    from toolbox.ortho.vertical import dem_in_photo_datum
    from toolbox.ui.photogrammetry import rpc_gcps

    image = params["INPUT"]
    crs = rpc_crs(params["CRS"], params["DEM"])
    camera = read_rpc(image.path, crs)
    bias = None
    if params["CONTROL"] is not None:
        camera, bias = refine_from_gcps(camera, Path(image.path).name, *rpc_gcps(params, crs),
                                        params["BIAS"])
        feedback.push_info(f"RPC {bias['model']} bias from {bias['gcps']} GCPs: RMS "
                           f"{bias['rms_before_px']:.3f} -> {bias['rms_after_px']:.3f} px")
    with dem_in_photo_datum(params["DEM"], params["BAND"], params["HEIGHTS"] or "ellipsoidal",
                            None, feedback, executor, params["OUTPUT"]) as (dem, band, heights):
        grid, gsd = rpc_plan(camera, dem, band, *grid_choice(params, crs))
        options = OrthoOptions(
            resampling=params["RESAMPLING"], outside=params["OUTSIDE"], nodata=params["NODATA"],
            dem_factor=params["DEM_FACTOR"], band=band, overviews=params["OVERVIEWS"],
            cog=params["COG"])
        report = rpc_orthorectify(camera, image, dem, grid, params["OUTPUT"], options, feedback,
                                  executor=executor)
    report.update(photo=Path(image.path).stem, photo_gsd_m=gsd, heights=heights.as_dict(),
                  bias=bias)
    return report


def grid_choice(params: dict[str, Any], crs: Any) -> tuple[Any, Any, tuple[float, float]]:
    """(cell, bounds, lattice origin) from CELL_SIZE, EXTENT and TEMPLATE."""
    from toolbox.io.crs import extent_bounds_in
    from toolbox.raster.grid_request import template_lattice

    cell = params["CELL_SIZE"]
    extent = params["EXTENT"]
    origin = (0.0, 0.0)
    if params["TEMPLATE"] is not None:
        cell, origin = template_lattice(params["TEMPLATE"], cell, crs, "the ortho")
    return cell, None if extent is None else extent_bounds_in(extent, crs), origin


def oriented_photo(params: dict[str, Any]) -> tuple[Any, Any, Any]:
    """The oriented photo, its orientation's CRS and the ortho's CRS (None: the same) from
    PROJECT/PHOTO (CRS = the ortho's) or CAMERA/EXTERIOR (CRS = the orientation's)."""
    from toolbox.photogrammetry.tables import load_project_parameter

    crs = params["CRS"]
    if params["PROJECT"] is not None:
        project = load_project_parameter(params["PROJECT"])
        photo = pick_photo(project, params["PHOTO"], params["INPUT"].path)
        return photo, project.crs if project.crs is not None else crs, crs
    return camera_photo(params), crs, None


def pick_photo(project: Any, photo_id: str | None, image: Any) -> Any:
    if photo_id is not None:
        photo = project.photo(photo_id)
    else:
        matches = [p for p in project.photos.values()
                   if (p.image is not None and Path(p.image).name == Path(image).name)
                   or p.id == Path(image).stem]
        if len(matches) != 1:
            raise ParameterError("PHOTO", f"is needed: {len(matches)} photos of the project "
                                 f"match the image '{Path(image).name}' (photos: "
                                 f"{', '.join(project.photos)})")
        photo = matches[0]
    if photo.exterior is None:
        raise InputDataError(f"photo {photo.id!r} has no exterior orientation in the project")
    return photo


def camera_photo(params: dict[str, Any]) -> Any:
    """A photo from a camera YAML, EXTERIOR, ANGLE_UNIT and the image size of INPUT."""
    import yaml

    from toolbox.photogrammetry.project import project_from_dict

    path = params["CAMERA"]
    try:
        spec = yaml.safe_load(path.read_text(encoding="utf-8"))
    except (OSError, yaml.YAMLError) as exc:
        raise ParameterError("CAMERA", f"cannot read '{path}': {exc}") from None
    if isinstance(spec, dict) and "cameras" in spec and isinstance(spec["cameras"], list) \
            and len(spec["cameras"]) == 1:
        spec = spec["cameras"][0]
    if not isinstance(spec, dict):
        raise ParameterError("CAMERA", f"'{path}' must hold one camera mapping")
    spec = dict(spec)
    info = params["INPUT"]
    if "model" not in spec:  # a camera model carries its im_size
        spec.setdefault("image_size_px", [info.width, info.height])
    try:
        values = [float(v) for v in params["EXTERIOR"].replace(";", ",").split(",")]
    except ValueError:
        values = []
    if len(values) != 6:
        raise ParameterError("EXTERIOR", f"must be 6 numbers X0,Y0,Z0,omega,phi,kappa, got "
                             f"{params['EXTERIOR']!r}")
    keys = ("X0", "Y0", "Z0", "omega", "phi", "kappa")
    doc = {"crs": None if params["CRS"] is None else params["CRS"].to_wkt(),
           "angle_unit": params["ANGLE_UNIT"], "cameras": [spec],
           "photos": [{"id": Path(info.path).stem, "camera": spec.get("name"),
                       "exterior": dict(zip(keys, values, strict=True))}]}
    try:
        project = project_from_dict(doc, path.parent, str(path))
    except InputDataError as exc:
        raise ParameterError("CAMERA", str(exc)) from None
    photo = next(iter(project.photos.values()))
    if params["PIXEL_TO_IMAGE"] is not None and photo.is_model:
        raise ParameterError("PIXEL_TO_IMAGE", "applies to film cameras only; the camera model "
                             "maps its own pixels")
    if params["PIXEL_TO_IMAGE"] is not None:
        from dataclasses import replace

        from toolbox.photogrammetry.fiducials import InteriorOrientation
        from toolbox.transforms.rectification import parse_pixel_to_image

        matrix = parse_pixel_to_image(params["PIXEL_TO_IMAGE"])
        photo = replace(photo, interior=InteriorOrientation(
            matrix, "homography" if matrix[2, :2].any() else "affine"))
    if photo.pixel_transform is None and not photo.is_model:
        raise ParameterError("CAMERA", "needs pixel_size_mm (and image_size_px), or give "
                             "PIXEL_TO_IMAGE, to relate the photo's pixels to image mm")
    return photo
