"""dsage_ray."""
