"""Stage 6, outputs for people: figures (`plot`) and rerun recordings (`rerun_log`)."""
