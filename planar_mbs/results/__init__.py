"""What a run gives: the table of signals (`signals`), the HDF5 file and the in-memory
`Results` (`hdf5`), the Poincaré section (`section`), results read for people (`views`: the slider,
the turning body, Poincaré points, time windows) and verdicts on the motion (`analysis`)."""
