import sys

from toolbox.cli import console

sys.exit(console())
