#include "data/mpm/scene_meshing.hpp"

#include <gmsh.h>

#include <algorithm>
#include <cmath>

#include "core/error.hpp"
#include "core/gmsh_session.hpp"
#include "data/mpm/background.hpp"

namespace bsms::mpm {

namespace {

constexpr double kPi = 3.14159265358979323846;

void set_mesh_options(double size) {
  gmsh::option::setNumber("Mesh.MeshSizeMin", size);
  gmsh::option::setNumber("Mesh.MeshSizeMax", size);
  gmsh::option::setNumber("Mesh.MeshSizeFromPoints", 0);
  gmsh::option::setNumber("Mesh.MeshSizeFromCurvature", 0);
  gmsh::option::setNumber("Mesh.MeshSizeExtendFromBoundary", 0);
  gmsh::option::setNumber("Mesh.Algorithm", 5);    // Delaunay, as in the paper
  gmsh::option::setNumber("Mesh.Algorithm3D", 1);  // Delaunay
  gmsh::option::setNumber("Mesh.RandomSeed", 1);
}

// Transfinite constraints on every curve/surface/volume: a regular lattice of nodes.
void make_structured(double size) {
  gmsh::vectorpair curves;
  gmsh::model::getEntities(curves, 1);
  for (const auto& [dim, tag] : curves) {
    double x0, y0, z0, x1, y1, z1;
    gmsh::model::getBoundingBox(dim, tag, x0, y0, z0, x1, y1, z1);
    const double len =
        std::sqrt((x1 - x0) * (x1 - x0) + (y1 - y0) * (y1 - y0) + (z1 - z0) * (z1 - z0));
    gmsh::model::mesh::setTransfiniteCurve(
        tag, std::max(2, static_cast<int>(std::lround(len / size)) + 1));
  }
  gmsh::vectorpair surfaces, volumes;
  gmsh::model::getEntities(surfaces, 2);
  for (const auto& s : surfaces)
    gmsh::model::mesh::setTransfiniteSurface(s.second, "AlternateLeft");
  gmsh::model::getEntities(volumes, 3);
  for (const auto& v : volumes) gmsh::model::mesh::setTransfiniteVolume(v.second);
}

Mesh mesh_box_background(const BackgroundSpec& spec, int dim, const std::string& context) {
  GmshSession session;
  set_mesh_options(spec.element_size);
  const std::vector<double>& lo = spec.min;
  const std::vector<double>& hi = spec.max;
  int tag;
  if (dim == 2) {
    tag = gmsh::model::occ::addRectangle(lo[0], lo[1], 0.0, hi[0] - lo[0], hi[1] - lo[1]);
  } else {
    tag =
        gmsh::model::occ::addBox(lo[0], lo[1], lo[2], hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]);
  }
  gmsh::model::occ::synchronize();
  // Classify the sides before any rotation (tags survive the rotation).
  std::vector<int> sides[3][2];
  gmsh::vectorpair faces;
  gmsh::model::getEntities(faces, dim - 1);
  const double tol = 1e-4 * spec.element_size;  // OCC pads bounding boxes
  for (const auto& f : faces) {
    double b[6];
    gmsh::model::getBoundingBox(f.first, f.second, b[0], b[1], b[2], b[3], b[4], b[5]);
    for (int a = 0; a < dim; ++a) {
      if (b[3 + a] - b[a] > tol) continue;
      if (std::abs(b[a] - lo[a]) < tol) sides[a][0].push_back(f.second);
      if (std::abs(b[a] - hi[a]) < tol) sides[a][1].push_back(f.second);
    }
  }
  if (spec.rotation_deg != 0.0) {
    std::vector<double> c = spec.rotation_center;
    if (c.empty())
      for (int a = 0; a < dim; ++a) c.push_back(0.5 * (lo[a] + hi[a]));
    gmsh::model::occ::rotate({{dim, tag}}, c[0], c[1], dim == 3 ? c[2] : 0.0, 0, 0, 1,
                             spec.rotation_deg * kPi / 180.0);
    gmsh::model::occ::synchronize();
  }
  for (int a = 0; a < dim; ++a)
    for (int s = 0; s < 2; ++s) {
      const int group = gmsh::model::addPhysicalGroup(dim - 1, sides[a][s]);
      gmsh::model::setPhysicalName(dim - 1, group, box_side_name(a, s != 0));
    }
  for (const auto& line : spec.embedded_lines) {
    const int a = gmsh::model::occ::addPoint(line[0], line[1], 0.0);
    const int b = gmsh::model::occ::addPoint(line[2], line[3], 0.0);
    const int segment = gmsh::model::occ::addLine(a, b);
    gmsh::model::occ::synchronize();
    gmsh::model::mesh::embed(1, {segment}, 2, tag);
  }
  const int domain = gmsh::model::addPhysicalGroup(dim, {tag});
  gmsh::model::setPhysicalName(dim, domain, "domain");
  if (spec.structured) make_structured(spec.element_size);
  gmsh::model::mesh::generate(dim);
  return session.extract_mesh(context);
}

Mesh mesh_ball_background(const BackgroundSpec& spec, int dim, const std::string& context) {
  GmshSession session;
  set_mesh_options(spec.element_size);
  const std::vector<double>& c = spec.center;
  const int tag = dim == 2 ? gmsh::model::occ::addDisk(c[0], c[1], 0.0, spec.radius, spec.radius)
                           : gmsh::model::occ::addSphere(c[0], c[1], c[2], spec.radius);
  gmsh::model::occ::synchronize();
  gmsh::vectorpair boundary;
  gmsh::model::getBoundary({{dim, tag}}, boundary, false, false, false);
  std::vector<int> faces;
  for (const auto& b : boundary) faces.push_back(std::abs(b.second));
  gmsh::model::setPhysicalName(dim - 1, gmsh::model::addPhysicalGroup(dim - 1, faces), "wall");
  gmsh::model::setPhysicalName(dim, gmsh::model::addPhysicalGroup(dim, {tag}), "domain");
  gmsh::model::mesh::generate(dim);
  return session.extract_mesh(context);
}

}  // namespace

Mesh mesh_background(const BackgroundSpec& spec, int dim, const std::string& context) {
  if (spec.type == "mesh") return read_mesh(spec.path);
  return spec.type == "ball" ? mesh_ball_background(spec, dim, context)
                             : mesh_box_background(spec, dim, context);
}

Mesh mesh_body(const BodySpec& body, int dim, const std::string& context) {
  if (body.shape.type == "mesh") return read_mesh(body.shape.path);
  GmshSession session;
  set_mesh_options(body.spacing);
  ShapeSpec s = body.shape;
  const bool centres = body.sampling == "cell_centres";
  if (centres)
    for (int a = 0; a < dim; ++a) {
      // Whole cells of size `spacing` (the box is assumed to hold an integer number of them).
      const double cells = std::max(1.0, std::round((s.max[a] - s.min[a]) / body.spacing));
      const double step = (s.max[a] - s.min[a]) / cells;
      s.min[a] += 0.5 * step;
      s.max[a] -= 0.5 * step;
      if (cells < 2.0)
        throw InputError(context + ": cell_centres sampling needs at least 2 cells per axis");
    }
  if (s.type == "box") {
    if (dim == 2) {
      gmsh::model::occ::addRectangle(s.min[0], s.min[1], 0.0, s.max[0] - s.min[0],
                                     s.max[1] - s.min[1]);
    } else {
      gmsh::model::occ::addBox(s.min[0], s.min[1], s.min[2], s.max[0] - s.min[0],
                               s.max[1] - s.min[1], s.max[2] - s.min[2]);
    }
  } else if (s.type == "disk") {
    gmsh::model::occ::addDisk(s.center[0], s.center[1], 0.0, s.radius, s.radius);
  } else if (s.type == "polygon") {
    std::vector<int> points, lines;
    for (const auto& p : s.points) points.push_back(gmsh::model::occ::addPoint(p[0], p[1], 0.0));
    for (size_t i = 0; i < points.size(); ++i)
      lines.push_back(gmsh::model::occ::addLine(points[i], points[(i + 1) % points.size()]));
    gmsh::model::occ::addPlaneSurface({gmsh::model::occ::addCurveLoop(lines)});
  } else {
    gmsh::model::occ::addSphere(s.center[0], s.center[1], s.center[2], s.radius);
  }
  gmsh::model::occ::synchronize();
  if (s.type == "box" && (body.structured || centres)) make_structured(body.spacing);
  gmsh::model::mesh::generate(dim);
  return session.extract_mesh(context);
}

}  // namespace bsms::mpm
