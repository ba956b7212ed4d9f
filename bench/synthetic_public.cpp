// Writes a split in DeepMind's MeshGraphNets format (meta.json + SPLIT.tfrecord) of any size, with
// smooth synthetic flow fields on a channel mesh, for measuring reading and training at the size
// of the real datasets: cylinder_flow's train split is 1,000 trajectories x 600 frames x ~1,900
// nodes (~13 GB), airfoil's ~5,200 nodes. Every trajectory has its own mesh topology (cell
// diagonals drawn per trajectory), as every cylinder_flow trajectory has its own mesh.
//
//   synthetic_public OUT_DIR [--split train] [--trajectories 1000] [--frames 600] [--nodes 1900]
//                    [--airfoil] [--seed 0]
//
// Writes OUT_DIR/SPLIT.tfrecord through a temporary name, and OUT_DIR/meta.json when missing.
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

#include "data/dataset/tfrecord.hpp"

namespace {

void put_varint(std::string& out, uint64_t v) {
  while (v >= 0x80) {
    out.push_back(static_cast<char>((v & 0x7F) | 0x80));
    v >>= 7;
  }
  out.push_back(static_cast<char>(v));
}

// Tag (field number, length-delimited) and length of a payload of `size` bytes.
void put_header(std::string& out, int number, uint64_t size) {
  put_varint(out, static_cast<uint64_t>(number) << 3 | 2);
  put_varint(out, size);
}

uint64_t varint_size(uint64_t v) {
  uint64_t n = 1;
  while (v >= 0x80) {
    v >>= 7;
    ++n;
  }
  return n;
}

uint64_t ld_size(int number, uint64_t payload) {
  return varint_size(static_cast<uint64_t>(number) << 3 | 2) + varint_size(payload) + payload;
}

// One feature-map entry {key: Feature{bytes_list: BytesList{value: bytes}}}, written into `out`.
void put_feature(std::string& out, const std::string& key, const void* data, uint64_t bytes) {
  const uint64_t list = ld_size(1, bytes);    // BytesList{value}
  const uint64_t feature = ld_size(1, list);  // Feature{bytes_list}
  const uint64_t entry = ld_size(1, key.size()) + ld_size(2, feature);
  put_header(out, 1, entry);  // Features.feature (map entry)
  put_header(out, 1, key.size());
  out += key;
  put_header(out, 2, feature);
  put_header(out, 1, list);
  put_header(out, 1, bytes);
  out.append(static_cast<const char*>(data), bytes);
}

uint64_t splitmix(uint64_t x) {
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}

struct Options {
  std::string out, split = "train";
  int64_t trajectories = 1000, frames = 600, nodes = 1900;
  bool airfoil = false;
  uint64_t seed = 0;
};

template <class T>
void append_le(std::string& s, T v) {
  char b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  s.append(b, sizeof(T));
}

std::string record(const Options& o, int64_t t) {
  const double length = 1.6, height = 0.41;
  const int64_t ny = std::max<int64_t>(3, std::lround(std::sqrt(o.nodes * height / length)));
  const int64_t nx = std::max<int64_t>(3, o.nodes / ny);
  const int64_t n = nx * ny;
  std::vector<float> pos(static_cast<size_t>(2 * n));
  std::vector<int32_t> type(static_cast<size_t>(n));
  for (int64_t j = 0; j < ny; ++j)
    for (int64_t i = 0; i < nx; ++i) {
      const int64_t v = j * nx + i;
      pos[2 * v] = static_cast<float>(length * i / (nx - 1));
      pos[2 * v + 1] = static_cast<float>(height * j / (ny - 1));
      type[v] = (j == 0 || j == ny - 1) ? 6 : i == 0 ? 4 : i == nx - 1 ? 5 : 0;
    }
  std::vector<int32_t> cells;
  for (int64_t j = 0; j + 1 < ny; ++j)
    for (int64_t i = 0; i + 1 < nx; ++i) {
      const int32_t a = static_cast<int32_t>(j * nx + i), b = a + 1,
                    c = static_cast<int32_t>(a + nx), d = c + 1;
      if (splitmix(o.seed ^ (static_cast<uint64_t>(t) << 32) ^ static_cast<uint64_t>(a)) & 1)
        cells.insert(cells.end(), {a, b, d, a, d, c});
      else
        cells.insert(cells.end(), {a, b, c, b, d, c});
    }
  const double phase = 0.37 * static_cast<double>(t) + 0.01 * static_cast<double>(o.seed);
  std::vector<float> vel(static_cast<size_t>(o.frames * n * 2)), pressure(o.frames * n), density;
  if (o.airfoil) density.resize(static_cast<size_t>(o.frames * n));
  for (int64_t k = 0; k < o.frames; ++k)
    for (int64_t v = 0; v < n; ++v) {
      const double x = pos[2 * v], y = pos[2 * v + 1];
      const double wave = 2 * M_PI * (x / 0.4 - 0.05 * static_cast<double>(k)) + phase;
      const double profile = 4 * y * (height - y) / (height * height);
      const size_t at = static_cast<size_t>(k * n + v);
      vel[2 * at] = static_cast<float>(profile * (1.0 + 0.2 * std::sin(wave)));
      vel[2 * at + 1] = static_cast<float>(0.1 * profile * std::cos(wave));
      pressure[at] = static_cast<float>(0.5 * std::sin(wave) - x);
      if (o.airfoil) density[at] = static_cast<float>(1.0 + 0.05 * std::cos(wave));
    }
  std::string features;
  features.reserve(vel.size() * 4 + pressure.size() * 8 + pos.size() * 4 + cells.size() * 4 + 1024);
  put_feature(features, "cells", cells.data(), cells.size() * 4);
  put_feature(features, "mesh_pos", pos.data(), pos.size() * 4);
  put_feature(features, "node_type", type.data(), type.size() * 4);
  put_feature(features, "velocity", vel.data(), vel.size() * 4);
  if (o.airfoil) put_feature(features, "density", density.data(), density.size() * 4);
  put_feature(features, "pressure", pressure.data(), pressure.size() * 4);
  std::string example;
  put_header(example, 1, features.size());  // Example.features
  example += features;
  return example;
}

std::string meta_json(const Options& o) {
  const std::string T = std::to_string(o.frames);
  std::string fields =
      R"("cells": {"type": "static", "shape": [1, -1, 3], "dtype": "int32"}, )"
      R"("mesh_pos": {"type": "static", "shape": [1, -1, 2], "dtype": "float32"}, )"
      R"("node_type": {"type": "static", "shape": [1, -1, 1], "dtype": "int32"}, )"
      R"("velocity": {"type": "dynamic", "shape": [)" +
      T + R"(, -1, 2], "dtype": "float32"}, )";
  if (o.airfoil)
    fields +=
        R"("density": {"type": "dynamic", "shape": [)" + T + R"(, -1, 1], "dtype": "float32"}, )";
  fields +=
      R"("pressure": {"type": "dynamic", "shape": [)" + T + R"(, -1, 1], "dtype": "float32"})";
  const std::string names =
      o.airfoil ? R"(["cells", "mesh_pos", "node_type", "velocity", "density", "pressure"])"
                : R"(["cells", "mesh_pos", "node_type", "velocity", "pressure"])";
  return std::string(R"({"simulator": ")") + (o.airfoil ? "su2" : "comsol") + R"(", "dt": )" +
         (o.airfoil ? "0.008" : "0.01") + R"(, "collision_radius": null, "features": {)" + fields +
         R"(}, "field_names": )" + names + R"(, "trajectory_length": )" + T + "}";
}

int usage(const std::string& why) {
  std::cerr << "synthetic_public: " << why
            << "\nusage: synthetic_public OUT_DIR [--split S] [--trajectories N] [--frames T] "
               "[--nodes N] [--airfoil] [--seed S]\n";
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) throw std::invalid_argument(a + " needs a value");
      return argv[++i];
    };
    try {
      if (a == "--split")
        o.split = value();
      else if (a == "--trajectories")
        o.trajectories = std::stoll(value());
      else if (a == "--frames")
        o.frames = std::stoll(value());
      else if (a == "--nodes")
        o.nodes = std::stoll(value());
      else if (a == "--seed")
        o.seed = std::stoull(value());
      else if (a == "--airfoil")
        o.airfoil = true;
      else if (!a.empty() && a[0] != '-' && o.out.empty())
        o.out = a;
      else
        return usage("unknown argument " + a);
    } catch (const std::exception& e) {
      return usage(a + ": " + e.what());
    }
  }
  if (o.out.empty()) return usage("OUT_DIR missing");
  if (o.trajectories < 1 || o.frames < 3 || o.nodes < 9)
    return usage("--trajectories >= 1, --frames >= 3 and --nodes >= 9 expected");
  namespace fs = std::filesystem;
  fs::create_directories(o.out);
  const fs::path meta = fs::path(o.out) / "meta.json";
  if (!fs::exists(meta)) std::ofstream(meta) << meta_json(o) << "\n";
  const fs::path path = fs::path(o.out) / (o.split + ".tfrecord");
  const std::string temp = path.string() + ".tmp";
  std::FILE* f = std::fopen(temp.c_str(), "wb");
  if (!f) return usage("cannot write " + temp);
  uint64_t total = 0;
  for (int64_t t = 0; t < o.trajectories; ++t) {
    const std::string data = record(o, t);
    std::string head;
    append_le<uint64_t>(head, data.size());
    append_le<uint32_t>(head, bsms::tfrecord::mask_crc(bsms::tfrecord::crc32c(head.data(), 8)));
    std::string tail;
    append_le<uint32_t>(tail,
                        bsms::tfrecord::mask_crc(bsms::tfrecord::crc32c(data.data(), data.size())));
    if (std::fwrite(head.data(), 1, head.size(), f) != head.size() ||
        std::fwrite(data.data(), 1, data.size(), f) != data.size() ||
        std::fwrite(tail.data(), 1, tail.size(), f) != tail.size()) {
      std::fclose(f);
      std::remove(temp.c_str());
      return usage("write failed (disk full?): " + temp);
    }
    total += head.size() + data.size() + tail.size();
  }
  if (std::fclose(f) != 0) return usage("write failed: " + temp);
  fs::rename(temp, path);
  std::cout << path.string() << ": " << o.trajectories << " trajectories, " << total << " bytes\n";
  return 0;
}
