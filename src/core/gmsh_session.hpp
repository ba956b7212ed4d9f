// Access to the gmsh library, whose state is global and not thread-safe. A GmshSession holds a
// process-wide lock, initialises gmsh once (terminal output off) and starts from an empty model;
// build geometry with gmsh::model::occ / geo inside it, then extract the mesh.
#pragma once

#include <memory>
#include <string>

#include "core/mesh.hpp"

namespace bsms {

class GmshSession {
 public:
  GmshSession();
  ~GmshSession();
  GmshSession(const GmshSession&) = delete;
  GmshSession& operator=(const GmshSession&) = delete;

  // Extracts the mesh of the current gmsh model with the semantics of read_mesh (assemble_mesh:
  // top dimension decides the cells, ascending node tags, unused nodes dropped, physical groups).
  // `context` prefixes error messages (usually the file name).
  Mesh extract_mesh(const std::string& context) const;

  // Discards gmsh's global state after a failed call (finalize); the next session re-initialises.
  void reset();

 private:
  struct Lock;
  std::unique_ptr<Lock> lock_;
};

}  // namespace bsms
