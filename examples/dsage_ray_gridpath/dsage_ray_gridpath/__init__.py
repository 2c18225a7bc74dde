"""GridPath: a toy DSAGE domain registered through the ``dsage_ray.domains`` entry point."""
