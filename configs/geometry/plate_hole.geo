// The 1M-node scale benchmark of README "Speed at scale": a 2 x 1 plate with a hole (radius 0.2).
// `gmsh -2 -setnumber lc 0.00148 plate_hole.geo -o plate_1m.msh` gives 992,712 nodes (MSH 4.1);
// without -setnumber, lc = 0.05 (~1K nodes; `bsms preprocess --mesh` meshes it on the fly).
SetFactory("OpenCASCADE");
If (!Exists(lc))
  lc = 0.05;
EndIf
Rectangle(1) = {0, 0, 0, 2, 1};
Disk(2) = {0.6, 0.5, 0, 0.2, 0.2};
BooleanDifference(3) = { Surface{1}; Delete; }{ Surface{2}; Delete; };
Physical Surface("plate") = {3};
Physical Curve("boundary") = {1, 2, 3, 4, 5};
Mesh.CharacteristicLengthMax = lc;
Mesh.CharacteristicLengthMin = lc;
Mesh.MshFileVersion = 4.1;
