"""Layer 1, the surrogate: response atlases of the physics (:mod:`~plate_env.surrogate.atlas`), an atlas conditioned
on a lab's known inputs (:mod:`~plate_env.surrogate.conditioning`) and the catalog of shipped atlas families
(:mod:`~plate_env.surrogate.catalog`). Imports only :mod:`plate_env.core`."""
