"""Reading DIC exports as they are written (docs/dic.md): layouts, the camera frame, binning
and the noise estimate, into the measurement contract."""
