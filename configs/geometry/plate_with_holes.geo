// Default demo geometry: a 4 x 1 plate with three circular holes (2D, triangles, ~3K nodes).
// `bsms preprocess --mesh configs/geometry/plate_with_holes.geo` meshes it on the fly.
SetFactory("OpenCASCADE");
Rectangle(1) = {0, 0, 0, 4, 1};
Disk(2) = {0.8, 0.5, 0, 0.25, 0.25};
Disk(3) = {2.0, 0.35, 0, 0.2, 0.2};
Disk(4) = {3.1, 0.6, 0, 0.3, 0.3};
BooleanDifference(5) = { Surface{1}; Delete; }{ Surface{2, 3, 4}; Delete; };
Physical Surface("plate") = {5};
Mesh.CharacteristicLengthMax = 0.04;
Mesh.CharacteristicLengthMin = 0.04;
