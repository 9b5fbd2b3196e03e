"""Runs inside Debian's QGIS Python (not the toolbox's venv): loads the provider in PyQGIS,
checks every spec became an algorithm with the right parameter types, and runs the algorithms
asked for with processing.run. Prints one JSON document on stdout.

usage: python3 qgis_check.py PLUGIN_DIR TOOLBOX_EXECUTABLE [CASES_JSON]
CASES_JSON: [{"id": "dem:idw", "qgis": {NAME: value...}}, ...] run with processing.run.
"""

import json
import os
import sys

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
plugin_dir, executable = sys.argv[1], sys.argv[2]
cases = json.loads(open(sys.argv[3]).read()) if len(sys.argv) > 3 else []
os.environ["PHOTOGRAMMETRY_TOOLBOX"] = executable
sys.path.insert(0, plugin_dir)
sys.path.insert(0, "/usr/share/qgis/python/plugins")

from qgis.core import QgsApplication  # noqa: E402

app = QgsApplication([], False)
app.initQgis()
from processing.core.Processing import Processing  # noqa: E402

Processing.initialize()
import processing  # noqa: E402
from photogrammetry_toolbox.plugin import ToolboxPlugin  # noqa: E402

plugin = ToolboxPlugin()
plugin.initProcessing()
provider = plugin.provider
report = {"problem": provider.problem, "algorithms": {}, "runs": {}}
for alg in provider.algorithms():
    report["algorithms"][alg.name()] = {
        "group": alg.group(), "group_id": alg.groupId(), "display_name": alg.displayName(),
        "parameters": {p.name(): {"type": p.type(), "optional": bool(p.flags() & p.FlagOptional),
                                  "advanced": bool(p.flags() & p.FlagAdvanced),
                                  "label": p.description(), "help": p.help()}
                       for p in alg.parameterDefinitions()},
        "help": bool(alg.shortHelpString()), "help_text": alg.shortHelpString()}
report["raster_formats"] = list(provider.supportedOutputRasterLayerExtensions())
report["vector_formats"] = list(provider.supportedOutputVectorLayerExtensions())
for case in cases:
    qid = f"{provider.id()}:{case['id'].replace(':', '_')}"
    try:
        result = processing.run(qid, case["qgis"])
        report["runs"][case["id"]] = {"ok": True, "outputs": {k: str(v) for k, v in
                                                              result.items()}}
    except Exception as exc:  # reported to the test, which fails with the message
        report["runs"][case["id"]] = {"ok": False, "error": str(exc)}
print("QGIS_CHECK " + json.dumps(report))
app.exitQgis()
