"""``python -m toolbox.demo.styles [FOLDER]``: regenerate the example styles of the demo's code
and colour files (``styles/siena/`` by default; :func:`toolbox.styles.files.write_code_styles`).

Here, not in :mod:`toolbox.styles`: the styles library does not depend on the demo (the runner
imports it)."""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path


def main(folder: str = "styles/siena") -> int:
    from toolbox.demo.samples import restitution
    from toolbox.io.code_file import read_code_file, read_colour_file
    from toolbox.styles.files import write_code_styles

    with tempfile.TemporaryDirectory() as tmp:
        made = restitution.make(Path(tmp), {})
        files = write_code_styles(folder, read_code_file(made["restitution_codes"]),
                                  read_colour_file(made["restitution_colours"]))
    print(f"{len(files)} style files written")
    return 0


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:2]))
