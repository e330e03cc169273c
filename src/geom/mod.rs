//! Geometry: rays, boxes, triangles and the bit-exact intersection tests.
