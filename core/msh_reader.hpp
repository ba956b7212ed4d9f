// Direct reader of gmsh MSH files, versions 2.2 and 4.1, ASCII and binary (little-endian, 8-byte
// size_t): the file is mapped and parsed in one pass with std::from_chars, about ten times faster
// than reading it through gmsh (bench_preprocess BM_ReadMsh; docs/results.md). Parsing is one
// thread; the post-processing splits its loops over threads. The
// result is the same Mesh as read_mesh_with_gmsh gives: both paths end in assemble_mesh.
//
// What each format contributes, as gmsh itself reads it:
//   4.1: $Entities gives the physical tags of every entity; $Nodes entity blocks (parametric
//        coordinates skipped, tags in any order); $Elements entity blocks of one element type.
//   2.2: $Nodes is a plain list; each element carries its tags, the first the physical group, the
//        second the elementary entity (elements of a negative entity are skipped, as gmsh does).
//   Both: $PhysicalNames names groups (unnamed: "dim:tag"); a group of dimension >= 1 holds the
//        nodes of every element of its entities; a point group holds its point's node. Unknown
//        sections ($Periodic, $NodeData, $Comments, ...) are skipped.
// Malformed or truncated input is an InputError of one line naming the file, the section, the
// line (ASCII) or byte offset (binary) and what was expected; counts read from the file are
// checked against the bytes left before anything is allocated. The node and element totals of the
// 4.1 section headers are hints only (gmsh 4.8 writes them wrong when it saves a subset of the
// nodes); the entity blocks are read as they are.
#pragma once

#include <string>
#include <string_view>

#include "core/error.hpp"
#include "core/mesh.hpp"

namespace bsms {

// Valid MSH that the direct reader leaves to gmsh: partitioned meshes ($PartitionedEntities, 2.2
// elements with partition tags), byte-swapped binary, binary with a size_t other than 8 bytes,
// $ParametricNodes, variable-size elements (polygons, polyhedra). read_mesh catches it and reads
// the file with read_mesh_with_gmsh.
class MshNotHandled : public InputError {
 public:
  using InputError::InputError;
};

// Whether `head`, the first bytes of a file, starts (after blank lines) with a $MeshFormat line
// followed by version 2.2 or 4.1, i.e. whether read_mesh gives the file to read_msh.
bool is_direct_msh(std::string_view head);

// Parses MSH 2.2 / 4.1 held in memory into the parts of a gmsh model. `context` (the file name)
// prefixes error messages. Throws InputError (MshNotHandled for what is left to gmsh).
MeshParts parse_msh(std::string_view bytes, const std::string& context);

// parse_msh + assemble_mesh on a file (mapped, not copied) or on bytes in memory.
Mesh read_msh(const std::string& path);
Mesh read_msh_bytes(std::string_view bytes, const std::string& context);

}  // namespace bsms
