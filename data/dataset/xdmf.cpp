#include "data/dataset/xdmf.hpp"

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "core/error.hpp"
#include "core/hdf5_file.hpp"

namespace bsms {
namespace fs = std::filesystem;

void write_trajectory_xdmf(const Dataset& d, int64_t t, const std::string& xdmf_path) {
  if (d.is_public_layout())
    throw InputError(d.location() + ": XDMF export needs a bsms dataset file");
  const auto& mesh = d.mesh(t);
  const int64_t n = mesh.num_nodes(), c = mesh.num_cells(), frames = d.num_frames(t);
  const int dim = mesh.dim;
  char group[64];
  std::snprintf(group, sizeof group, "/trajectories/%06lld", static_cast<long long>(t));
  const fs::path base = fs::absolute(xdmf_path).parent_path();
  const std::string h5 = fs::relative(fs::absolute(d.location()), base).string();
  const char* topology = mesh.cell_size == 4   ? "Tetrahedron"
                         : mesh.cell_size == 3 ? "Triangle"
                                               : "Polyline";
  const double dt = d.frame_dt() > 0 ? d.frame_dt() : 1.0;
  const bool moving = d.has_field("world_pos");
  // Geometry: world positions when the nodes move (cloth: 3-D world, 2-D mesh), else the mesh.
  const int geometry_dim = moving ? d.dim() : dim;

  std::ostringstream x;
  x << "<?xml version=\"1.0\" ?>\n<Xdmf Version=\"3.0\">\n<Domain>\n"
    << "<Grid Name=\"trajectory_" << t
    << "\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
  auto slab = [&](const std::string& field, int64_t frame, int64_t width) {
    std::ostringstream s;
    const std::string dims =
        width > 1 ? std::to_string(n) + " " + std::to_string(width) : std::to_string(n);
    const std::string full = std::to_string(frames) + " " + std::to_string(n) +
                             (width > 1 ? " " + std::to_string(width) : "");
    const int rank = width > 1 ? 3 : 2;
    s << "<DataItem ItemType=\"HyperSlab\" Dimensions=\"" << dims << "\">\n"
      << "<DataItem Dimensions=\"3 " << rank << "\" Format=\"XML\">" << frame << " 0"
      << (rank == 3 ? " 0" : "") << " 1 1" << (rank == 3 ? " 1" : "") << " 1 " << n
      << (rank == 3 ? " " + std::to_string(width) : "") << "</DataItem>\n"
      << "<DataItem Dimensions=\"" << full
      << "\" NumberType=\"Float\" Precision=\"4\" Format=\"HDF\">" << h5 << ":" << group << "/"
      << field << "</DataItem>\n</DataItem>\n";
    return s.str();
  };
  for (int64_t f = 0; f < frames; ++f) {
    x << "<Grid Name=\"frame_" << f << "\" GridType=\"Uniform\">\n"
      << "<Time Value=\"" << f * dt << "\"/>\n"
      << "<Topology TopologyType=\"" << topology << "\" NumberOfElements=\"" << c << "\">\n"
      << "<DataItem Dimensions=\"" << c << " " << mesh.cell_size
      << "\" NumberType=\"Int\" Format=\"HDF\">" << h5 << ":" << group << "/cells</DataItem>\n"
      << "</Topology>\n"
      << "<Geometry GeometryType=\"" << (geometry_dim == 3 ? "XYZ" : "XY") << "\">\n";
    if (moving) {
      x << slab("world_pos", f, geometry_dim);
    } else {
      x << "<DataItem Dimensions=\"" << n << " " << dim
        << "\" NumberType=\"Float\" Precision=\"4\" Format=\"HDF\">" << h5 << ":" << group
        << "/mesh_pos</DataItem>\n";
    }
    x << "</Geometry>\n";
    for (const char* field : {"node_type", "body_id"}) {
      x << "<Attribute Name=\"" << field << "\" AttributeType=\"Scalar\" Center=\"Node\">\n"
        << "<DataItem Dimensions=\"" << n << "\" NumberType=\"Int\" Format=\"HDF\">" << h5 << ":"
        << group << "/" << field << "</DataItem>\n</Attribute>\n";
    }
    for (const auto& field : d.fields()) {
      if (field.name == "world_pos" && moving) continue;
      x << "<Attribute Name=\"" << field.name << "\" AttributeType=\""
        << (field.width > 1 ? "Vector" : "Scalar") << "\" Center=\"Node\">\n"
        << slab(field.name, f, field.width) << "</Attribute>\n";
    }
    x << "</Grid>\n";
  }
  x << "</Grid>\n</Domain>\n</Xdmf>\n";

  AtomicOutput out(xdmf_path);
  {
    std::ofstream file(out.temp_path());
    file << x.str();
    if (!file) throw IoError(xdmf_path + ": cannot write");
  }
  out.commit();
}

}  // namespace bsms
