"""Layer 7, building shipped artifacts: atlas grids named by data (:mod:`~plate_env.build.atlas_grid`) and the
object sets and probe grids of the calibration, atlas and evaluation builds (:mod:`~plate_env.build.eval_sets`)."""
