from toolbox.cli import script

script()
