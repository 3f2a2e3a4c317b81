"""The .mbs grammar (`mbs.lark`), shipped inside the wheel as `planar_mbs.language.grammar`."""
