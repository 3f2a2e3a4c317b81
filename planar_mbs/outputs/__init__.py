"""Stage 6, outputs for people: figures (`plot`) and rerun recordings (`rerun_log`), both reading
results through `planar_mbs.results.views`, and the figures of mode shapes (`modes_plot`)."""
