"""The `mbs` command line (typer), installed as `planar_mbs.cli`."""
