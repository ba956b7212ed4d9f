// libFuzzer target for the check of gmsh scripts (core/geo_scan.hpp): the input is a .geo text,
// scanned as read_mesh_with_gmsh scans a file before the gmsh worker runs it (gmsh itself is not
// run: libgmsh 4.8 crashes on its own after a few thousand models in one process). Any text must
// end in bounded time with findings in order, on lines of the text; and a SystemCall on the
// first line of any text without NUL bytes must be refused there, whatever follows. Seeds (the
// shipped geometries are copied in by `make fuzz`): BSMS_FUZZ_WRITE_SEEDS=DIR fuzz_geo.
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>
#include <vector>

#include "core/geo_scan.hpp"
#include "seeds.hpp"

namespace {

std::vector<std::vector<uint8_t>> seeds() {
  const char* texts[] = {
      "SetFactory(\"OpenCASCADE\");\nRectangle(1) = {0, 0, 0, 1, 1};\nMesh.MeshSizeMax = 0.1;\n",
      "Point(1) = {0, 0, 0, .1};\nExit;\n",
      "// SystemCall \"x\";\n/* Save \"y\"; */ s = \"Print 'z'\"; Print.Width = 8;\n",
      "For (1:2) /*\nSystemCall \"touch x\"; */\nEndFor\n",
      "For i In {1:3}\n  If (i == 2) Printf(\"%g\", i) > \"f\"; Else x = i; EndIf\nEndFor\n",
      "Macro m\n  Include \"a.geo\";\nReturn\nCall m;\nMerge StrCat(\"b\", \".step\");\n",
      "If (0) x = \"EndIf y = \"; // \" ; SystemCall \"p\";\nEndIf\nS2N[\"Exit\"];\n",
      "Plugin(Crack).Run; OnelabRun(\"c\"); CreateDir \"d\"; Save View[0] \"v.pos\";\n",
  };
  std::vector<std::vector<uint8_t>> out;
  for (const char* t : texts) out.emplace_back(t, t + std::strlen(t));
  return out;
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  bsms_fuzz::maybe_write_seeds(seeds);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  int lines = 1;
  for (char c : text) lines += c == '\n';
  const std::vector<bsms::GeoFinding> found = bsms::scan_geo_script(text);
  for (size_t i = 0; i < found.size(); ++i) {
    const bsms::GeoFinding& f = found[i];
    if (f.offset > size || f.line < 1 || f.line > lines || f.command.empty() ||
        f.command.size() > 64 || (i > 0 && found[i - 1].offset >= f.offset))
      __builtin_trap();
    if (!f.refused() && f.include.size() > 1023) __builtin_trap();
  }
  if (std::memchr(data, 0, size) == nullptr) {
    const std::string prefixed = "SystemCall \"x\";\n" + std::string(text);
    const std::vector<bsms::GeoFinding> first = bsms::scan_geo_script(prefixed);
    if (first.empty() || first[0].offset != 0 || first[0].command != "SystemCall" ||
        !first[0].refused() || first[0].line != 1)
      __builtin_trap();
  }
  return 0;
}
