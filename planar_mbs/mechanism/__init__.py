"""Stage 2, the mechanism: a `ModelSpec` compiled into the flat arrays of a `Model` (`compile`,
`model`; loads and motions into expression programs, `expressions`, and tables into piecewise
cubics, `tables`), its constraint rows ordered for the envelope solver (`ordering`) and its initial
pose assembled on the constraints (`kinematics`)."""
