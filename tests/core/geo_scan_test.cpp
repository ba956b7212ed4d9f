#include "core/geo_scan.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <random>
#include <string>

#include "core/error.hpp"
#include "tests/temp_dir.hpp"

namespace bsms {
namespace {

namespace fs = std::filesystem;

// The first refusal of a script's text, as "LINE:WORD", or "" when none.
std::string refused(const std::string& text) {
  for (const GeoFinding& f : scan_geo_script(text))
    if (f.refused()) return std::to_string(f.line) + ":" + f.command;
  return "";
}

TEST(GeoScan, RefusesCommandsThatReachOutside) {
  EXPECT_EQ(refused("Point(1) = {0, 0, 0};\nSystemCall \"touch x\";\n"), "2:SystemCall");
  EXPECT_EQ(refused("System \"ls\";"), "1:System");
  EXPECT_EQ(refused("NonBlockingSystemCall \"sleep 9\";"), "1:NonBlockingSystemCall");
  EXPECT_EQ(refused("OnelabRun(\"client\", \"ls\");"), "1:OnelabRun");
  EXPECT_EQ(refused("x = 1;\n\nExit;"), "3:Exit");
  EXPECT_EQ(refused("Save \"out.msh\";"), "1:Save");
  EXPECT_EQ(refused("Save View[0] \"v.pos\";"), "1:Save");
  EXPECT_EQ(refused("Save Sprintf(\"m%g.msh\", 1);"), "1:Save");
  EXPECT_EQ(refused("Print \"shot.png\";"), "1:Print");
  EXPECT_EQ(refused("CreateDir \"d\";"), "1:CreateDir");
  EXPECT_EQ(refused("Plugin(Crack).Run;"), "1:Plugin");
  EXPECT_EQ(refused("S2N[\"SystemCall\"] \"ls\";"), "1:S2N");
  EXPECT_EQ(refused("StringToName[StrCat(\"Sys\", \"tem\")] \"ls\";"), "1:StringToName");
  EXPECT_EQ(refused("Printf(\"x\") > \"f.txt\";"), "1:Printf");
  EXPECT_EQ(refused("Printf(\"%g\", 1) >> \"f.txt\";"), "1:Printf");
  EXPECT_EQ(refused("Include StrCat(\"a\", \".geo\");"), "1:Include");
  EXPECT_EQ(refused("Merge Sprintf(\"p%g.step\", 1);"), "1:Merge");
  // gmsh reads `2Exit` as a number and Exit.
  EXPECT_EQ(refused("2Exit;"), "1:Exit");
}

TEST(GeoScan, LeavesCommentsStringsNamesAndOptionsAlone) {
  EXPECT_EQ(refused("// SystemCall \"touch x\";\nPoint(1) = {0, 0, 0};"), "");
  EXPECT_EQ(refused("/* Exit;\n   Save \"x.msh\"; */ Point(1) = {0, 0, 0};"), "");
  EXPECT_EQ(refused("s = \"SystemCall 'x'; Exit;\"; t = 'Save \"y\"';"), "");
  EXPECT_EQ(refused("Print.Width = 800; Print.Format = 4;"), "");
  EXPECT_EQ(refused("Save = 3; Save += 1; Print~{2} = 1; Merge[] = {1, 2};"), "");
  EXPECT_EQ(refused("MySystemCall = 1; Exits = 2; SaveAll = 3;"), "");
  // gmsh's words are case-sensitive: these are unknown commands to it, harmless.
  EXPECT_EQ(refused("systemcall \"x\"; exit; SAVE \"y\";"), "");
  EXPECT_EQ(refused("Printf(\"a > b\"); Printf(\"%g\", (2 > 1)); Printf(\"%g\", x[1 >> 0]);"), "");
  EXPECT_EQ(
      refused("Mesh.MeshSizeMax = 0.1; Mesh 2; Delete Physicals; SetFactory(\"OpenCASCADE\");"),
      "");
}

TEST(GeoScan, FollowsLiteralIncludes) {
  const auto found = scan_geo_script("Include \"params.geo\";\nMerge 'part.step';\n");
  ASSERT_EQ(found.size(), 2u);
  EXPECT_FALSE(found[0].refused());
  EXPECT_EQ(found[0].include, "params.geo");
  EXPECT_EQ(found[0].line, 1);
  EXPECT_EQ(found[1].include, "part.step");
  EXPECT_EQ(found[1].line, 2);
}

// Text that a first pass reads as a comment or a string but gmsh runs as code on another.
TEST(GeoScan, SeesCodeGmshReadsOnAnotherPass) {
  // A For loop's next pass starts at the line after its header: inside the comment.
  EXPECT_EQ(refused("For (1:2) /*\nSystemCall \"touch x\"; */\nEndFor\n"), "2:SystemCall");
  EXPECT_EQ(refused("Macro m /*\nExit; */\nReturn\nCall m;\n"), "2:Exit");
  // A false If is skipped by a search for EndIf that ignores strings.
  EXPECT_EQ(refused("If (0) x = \"EndIf y = \"; // \" ; SystemCall \"touch p\";\nEndIf\n"),
            "1:SystemCall");
  // gmsh keeps 1023 characters of a string and reads on after the next one.
  const std::string cut = "s = \"" + std::string(1023, 'a') + "X; SystemCall \"t\"; // \";\n";
  EXPECT_EQ(refused(cut), "1:SystemCall");
  EXPECT_EQ(refused("s = \"" + std::string(1023, 'a') + "\"; x = 1;"), "");
  // Long lines are read in pieces: a piece can end inside a word.
  const std::string long_line =
      "For (1:2) x = 1; " + std::string(9000, 'X') + "SystemCall \"t\";\nEndFor\n";
  EXPECT_EQ(refused(long_line), "1:SystemCall");
  EXPECT_EQ(refused(std::string("Point(1) = {0, 0, 0};\n\0Exit;", 28)), "2:NUL");
}

TEST(GeoScan, ArbitraryBytesEndQuickly) {
  std::mt19937 rng(7);
  const std::string alphabet = "ab/*\"'\n\r;(){}[]<>=.EndIfElseReturnForMacroSystemCall 0123";
  for (int trial = 0; trial < 200; ++trial) {
    std::string text(1 + rng() % 3000, ' ');
    for (char& c : text) c = alphabet[rng() % alphabet.size()];
    const auto found = scan_geo_script(text);
    for (const GeoFinding& f : found) {
      EXPECT_LE(f.offset, text.size());
      EXPECT_GE(f.line, 1);
    }
  }
}

class GeoFiles : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = bsms::testing::unique_temp_dir("geo_scan");
    fs::create_directories(dir_ / "sub");
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string write(const std::string& name, const std::string& text) {
    const fs::path p = dir_ / name;
    std::ofstream(p, std::ios::binary) << text;
    return p.string();
  }
  std::string error_of(const std::string& path) {
    try {
      check_geo_script(path);
    } catch (const InputError& e) {
      return e.what();
    }
    return "";
  }
  fs::path dir_;
};

TEST_F(GeoFiles, RefusalNamesTheFileTheLineAndTheCommand) {
  const std::string geo = write("e.geo", "Point(1) = {0, 0, 0, .1};\nExit;\n");
  const std::string error = error_of(geo);
  EXPECT_EQ(error.find(geo + ":2: gmsh command 'Exit' ends the process; refused"), 0u) << error;
  EXPECT_NE(error.find("--allow-geo-commands"), std::string::npos) << error;
  EXPECT_EQ(error.find('\n'), std::string::npos);
}

TEST_F(GeoFiles, IncludedScriptsAreCheckedWhereGmshFindsThem) {
  write("sub/inner.geo", "x = 1;\nSystemCall \"touch pwned\";\n");
  write("sub/middle.geo", "Include \"inner.geo\";\n");  // relative to sub/, as gmsh resolves it
  const std::string top = write("top.geo", "lc = 0.1;\nInclude \"sub/middle.geo\";\n");
  const std::string error = error_of(top);
  EXPECT_EQ(error.find((dir_ / "sub/inner.geo").string() + ":2 (included from "), 0u) << error;
  EXPECT_NE(error.find("middle.geo:1): gmsh command 'SystemCall' runs a shell command"),
            std::string::npos)
      << error;
  // A script that includes itself, a missing file and a CAD file pass the check.
  const std::string loop = write("loop.geo", "Include \"loop.geo\";\nMerge \"part.step\";\n");
  write("part.step", "ISO-10303-21; Exit; SystemCall\n");
  EXPECT_EQ(error_of(loop), "");
  EXPECT_EQ(error_of(write("missing.geo", "Include \"nowhere.geo\";\n")), "");
  // Include reads any file as a script, whatever its name.
  write("cmd.step", "Exit;\n");
  EXPECT_NE(error_of(write("inc_step.geo", "Include \"cmd.step\";\n")).find("cmd.step:1 (included"),
            std::string::npos);
}

TEST_F(GeoFiles, ScriptsAreTheFilesGmshParses) {
  EXPECT_TRUE(is_gmsh_script(write("a.geo", "Point(1) = {0, 0, 0};\n")));
  EXPECT_TRUE(is_gmsh_script(write("a.txt", "Point(1) = {0, 0, 0};\n")));
  EXPECT_FALSE(is_gmsh_script(write("a.msh", "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n")));
  EXPECT_FALSE(is_gmsh_script(write("b.geo", "$MeshFormat\n2.2 0 8\n")));
  EXPECT_FALSE(is_gmsh_script(write("a.step", "ISO-10303-21;\n")));
  EXPECT_FALSE(is_gmsh_script(write("a.brep", "DBRep_DrawableShape\n")));
}

TEST(GeoScan, ShippedGeometriesPass) {
  for (const auto& entry : fs::directory_iterator(fs::path(BSMS_SOURCE_DIR) / "configs/geometry")) {
    if (entry.path().extension() != ".geo") continue;
    EXPECT_NO_THROW(check_geo_script(entry.path().string())) << entry.path();
  }
}

}  // namespace
}  // namespace bsms
