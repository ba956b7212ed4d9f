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

// Reads `path` with the gmsh library in this process (a geometry is meshed first, as
// read_mesh_with_gmsh says). This is the gmsh worker's work (gmsh_worker.hpp): everything else
// calls read_mesh_with_gmsh, which runs it in a child process with limits. The caller has checked
// that the file exists and, for a script, its commands.
Mesh read_mesh_with_gmsh_here(const std::string& path);

}  // namespace bsms
