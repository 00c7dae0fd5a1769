"""Triangle meshes: the facet data RFT integrates over, STL I/O, parametric shapes."""
