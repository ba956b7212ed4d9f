#include "data/dataset/xdmf.hpp"

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "core/error.hpp"
#include "core/hdf5_file.hpp"
#include "core/xdmf_text.hpp"

namespace bsms {
namespace fs = std::filesystem;

namespace {

// Components of a field's view: 0 for a scalar ([N]), 3 for vectors, else the field's width.
hsize_t view_width(int64_t width) {
  return width <= 1 ? 0 : width <= 3 ? 3 : static_cast<hsize_t>(width);
}

std::string dims(int64_t n, hsize_t width) {
  return width > 0 ? std::to_string(n) + " " + std::to_string(width) : std::to_string(n);
}

}  // namespace

std::string xdmf_views_path(const std::string& xdmf_path) {
  return xdmf_path + ".h5";
}

void write_trajectory_xdmf(const Dataset& d, int64_t t, const std::string& xdmf_path) {
  if (d.is_public_layout())
    throw InputError(d.location() +
                     ": XDMF describes bsms dataset files (bsms export --out converts this one)");
  const auto& mesh = d.mesh(t);
  const int64_t n = mesh.num_nodes(), c = mesh.num_cells(), frames = d.num_frames(t);
  const std::string group = "/trajectories/" + xdmf_index_name(t);
  const fs::path base = fs::absolute(xdmf_path).parent_path();
  const std::string h5 = fs::relative(fs::absolute(d.location()), base).string();
  const std::string views_path = xdmf_views_path(xdmf_path);
  const std::string views = fs::path(views_path).filename().string();
  const char* topology = mesh.cell_size == 4   ? (mesh.dim == 3 ? "Tetrahedron" : "Quadrilateral")
                         : mesh.cell_size == 3 ? "Triangle"
                         : mesh.cell_size == 2 ? "Polyline"
                                               : "Polyvertex";
  const double dt = d.frame_dt() > 0 ? d.frame_dt() : 1.0;
  const bool moving = d.has_field("world_pos");
  std::vector<FieldInfo> attributes;
  for (const auto& field : d.fields())
    if (!(field.name == "world_pos" && moving)) attributes.push_back(field);

  // The views: one virtual dataset per frame and field, mapping the dataset file (the mapping is
  // resolved from the views file's folder, the XDMF's, so `h5` is the right name there too).
  AtomicOutput views_out(views_path);
  {
    const H5File source(d.location(), H5File::Mode::kRead);
    H5File v(views_out.temp_path(), H5File::Mode::kTruncate);
    v.set_attr("/", "format", std::string("bsms-xdmf-views"));
    v.set_attr("/", "source", h5);
    if (moving) {
      const Shape shape = source.shape(group + "/world_pos");
      for (int64_t f = 0; f < frames; ++f)
        v.write_virtual("/world_pos/" + xdmf_index_name(f), h5, group + "/world_pos", shape, f, 3);
    } else {
      v.write_virtual("/mesh_pos", h5, group + "/mesh_pos", source.shape(group + "/mesh_pos"), -1,
                      3);
    }
    for (const auto& field : attributes) {
      const Shape shape = source.shape(group + "/" + field.name);
      for (int64_t f = 0; f < frames; ++f)
        v.write_virtual("/" + field.name + "/" + xdmf_index_name(f), h5, group + "/" + field.name,
                        shape, f, view_width(field.width));
    }
    v.close();
  }

  std::ostringstream x;
  x.precision(12);
  x << "<?xml version=\"1.0\" ?>\n<Xdmf Version=\"3.0\">\n<Domain>\n"
    << "<Grid Name=\"trajectory_" << t
    << "\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
  for (int64_t f = 0; f < frames; ++f) {
    x << "<Grid Name=\"frame_" << f << "\" GridType=\"Uniform\">\n"
      << "<Time Value=\"" << f * dt << "\"/>\n"
      << "<Topology TopologyType=\"" << topology << "\" NumberOfElements=\"" << c << "\"";
    if (mesh.cell_size <= 2) x << " NodesPerElement=\"" << mesh.cell_size << "\"";
    x << ">\n"
      << xdmf_hdf_item(std::to_string(c) + " " + std::to_string(mesh.cell_size), "Int", 4, h5,
                       group + "/cells")
      << "</Topology>\n<Geometry GeometryType=\"XYZ\">\n"
      << xdmf_hdf_item(dims(n, 3), "Float", 4, views,
                       moving ? "/world_pos/" + xdmf_index_name(f) : "/mesh_pos")
      << "</Geometry>\n";
    for (const char* field : {"node_type", "body_id"})
      x << "<Attribute Name=\"" << field << "\" AttributeType=\"Scalar\" Center=\"Node\">\n"
        << xdmf_hdf_item(std::to_string(n), "Int", 4, h5, group + "/" + field) << "</Attribute>\n";
    for (const auto& field : attributes) {
      const hsize_t width = view_width(field.width);
      x << "<Attribute Name=\"" << xml_escape(field.name) << "\" AttributeType=\""
        << (width == 0   ? "Scalar"
            : width == 3 ? "Vector"
                         : "Matrix")
        << "\" Center=\"Node\">\n"
        << xdmf_hdf_item(dims(n, width), "Float", 4, views,
                         "/" + field.name + "/" + xdmf_index_name(f))
        << "</Attribute>\n";
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
  views_out.commit();
  out.commit();
}

}  // namespace bsms
