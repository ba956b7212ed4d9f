// Pieces of XDMF text shared by the dataset XDMF (data/dataset/xdmf.cpp) and the solver's frames
// XDMF (data/mpm/simulation.cpp).
#pragma once

#include <cstdint>
#include <cstdio>
#include <string>

namespace bsms {

// The name of frame (or trajectory) `index` in an HDF5 group: six digits, "000012".
inline std::string xdmf_index_name(int64_t index) {
  char buf[24];
  std::snprintf(buf, sizeof buf, "%06lld", static_cast<long long>(index));
  return buf;
}

// `s` with the characters XML reserves in text and attributes escaped.
inline std::string xml_escape(const std::string& s) {
  std::string out;
  for (char c : s) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

// A DataItem reading the whole HDF5 dataset `dataset` of `file` (a path relative to the XDMF
// file's folder): `number_type` "Int" or "Float", `precision` in bytes.
inline std::string xdmf_hdf_item(const std::string& dims, const char* number_type, int precision,
                                 const std::string& file, const std::string& dataset) {
  return "<DataItem Dimensions=\"" + dims + "\" NumberType=\"" + number_type + "\" Precision=\"" +
         std::to_string(precision) + "\" Format=\"HDF\">" + xml_escape(file) + ":" + dataset +
         "</DataItem>\n";
}

}  // namespace bsms
