"""Target shapes (plate, box, ellipsoid, cylinder, capsule): parameters, facets, lattices;
the lowest room of the model, importing nothing else in it."""
