from toolbox.cli import main

main(prog_name="toolbox")
