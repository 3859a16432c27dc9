"""Sub-commands of the `contour` program; each module registers its own."""
