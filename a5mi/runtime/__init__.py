"""What a5mi runs on: the Mitsuba variant, the LLVM library, optional extras and the Dask clusters (local, or
workers started as SLURM jobs). Modules here may import a5mi's platform modules (errors, extras, paths) and the
cluster module; never the command layer, the renderer or the grader."""
