// OpenBLAS kernel choice (core/runtime.hpp): when OpenBLAS's DYNAMIC_ARCH detection falls back to
// kernels without AVX2 on a CPU that has it, bsms forces the vector kernels the CPU can run.
#include <gtest/gtest.h>

#include <fstream>
#include <set>
#include <sstream>
#include <string>

#include "core/runtime.hpp"

namespace bsms {
namespace {

CpuFeatures avx512_cpu() {
  CpuFeatures cpu;
  cpu.avx2 = cpu.fma = true;
  cpu.avx512f = cpu.avx512bw = cpu.avx512dq = cpu.avx512vl = cpu.avx512cd = true;
  return cpu;
}

CpuFeatures avx2_cpu() {
  CpuFeatures cpu;
  cpu.avx2 = cpu.fma = true;
  return cpu;
}

TEST(BlasCoreOverride, ScalarFallbackOnAVectorCpuGetsTheVectorKernels) {
  // Debian 12's OpenBLAS 0.3.21 on an Intel family 6 model 207 (unknown to it) says "Prescott".
  EXPECT_EQ(blas_core_override("Prescott", avx512_cpu()), "SkylakeX");
  EXPECT_EQ(blas_core_override("Prescott", avx2_cpu()), "Haswell");
  EXPECT_EQ(blas_core_override("Nehalem", avx2_cpu()), "Haswell");
  EXPECT_EQ(blas_core_override("Sandybridge", avx512_cpu()), "SkylakeX");  // AVX without AVX2
  EXPECT_EQ(blas_core_override("Core2", avx2_cpu()), "Haswell");
  EXPECT_EQ(blas_core_override("Unknown", avx2_cpu()), "Haswell");
}

TEST(BlasCoreOverride, PartialAvx512TakesTheAvx2Kernels) {
  // OpenBLAS's SkylakeX kernels use F, BW, DQ, VL and CD; without any of them: Haswell.
  for (bool CpuFeatures::*missing : {&CpuFeatures::avx512bw, &CpuFeatures::avx512dq,
                                     &CpuFeatures::avx512vl, &CpuFeatures::avx512cd}) {
    CpuFeatures cpu = avx512_cpu();
    cpu.*missing = false;
    EXPECT_EQ(blas_core_override("Prescott", cpu), "Haswell");
  }
  CpuFeatures no_fma = avx512_cpu();
  no_fma.avx512f = false;
  no_fma.fma = false;
  EXPECT_EQ(blas_core_override("Prescott", no_fma), "");  // neither kernel set can run
}

TEST(BlasCoreOverride, OpenBlasOwnVectorChoiceStands) {
  for (const char* core : {"Haswell", "Zen", "SkylakeX", "CooperLake", "Cooperlake",
                           "SapphireRapids", "HASWELL", "skylakex"}) {
    EXPECT_EQ(blas_core_override(core, avx512_cpu()), "") << core;
    EXPECT_EQ(blas_core_override(core, avx2_cpu()), "") << core;
  }
}

TEST(BlasCoreOverride, NothingToSteerWithoutOpenBlasOrVectorUnits) {
  EXPECT_EQ(blas_core_override("", avx512_cpu()), "");  // no OpenBLAS in the process
  EXPECT_EQ(blas_core_override("Prescott", CpuFeatures{}), "");
  CpuFeatures avx2_only;
  avx2_only.avx2 = true;  // no FMA: the Haswell kernels would fault
  EXPECT_EQ(blas_core_override("Prescott", avx2_only), "");
}

// glibc's malloc on transparent huge pages: the tunable added to whatever the user set, never
// over a hugetlb setting of theirs.
TEST(GlibcTunables, HugePagesAddedUnlessTheUserChoseThem) {
  EXPECT_EQ(glibc_tunables_with_huge_pages(""), "glibc.malloc.hugetlb=1");
  EXPECT_EQ(glibc_tunables_with_huge_pages("glibc.malloc.arena_max=2"),
            "glibc.malloc.arena_max=2:glibc.malloc.hugetlb=1");
  EXPECT_EQ(glibc_tunables_with_huge_pages("glibc.malloc.hugetlb=0"), "glibc.malloc.hugetlb=0");
  EXPECT_EQ(glibc_tunables_with_huge_pages("glibc.malloc.arena_max=2:glibc.malloc.hugetlb=2"),
            "glibc.malloc.arena_max=2:glibc.malloc.hugetlb=2");
}

TEST(CpuFeatures, AgreeWithTheKernelsFlags) {
  std::ifstream cpuinfo("/proc/cpuinfo");
  if (!cpuinfo) GTEST_SKIP() << "no /proc/cpuinfo";
  std::string line;
  std::set<std::string> flags;
  while (std::getline(cpuinfo, line)) {
    if (line.rfind("flags", 0) != 0) continue;
    std::istringstream words(line.substr(line.find(':') + 1));
    for (std::string w; words >> w;) flags.insert(w);
    break;
  }
  ASSERT_FALSE(flags.empty());
  const CpuFeatures cpu = cpu_features();
  EXPECT_EQ(cpu.avx2, flags.count("avx2") == 1);
  EXPECT_EQ(cpu.fma, flags.count("fma") == 1);
  EXPECT_EQ(cpu.avx512f, flags.count("avx512f") == 1);
  EXPECT_EQ(cpu.avx512bw, flags.count("avx512bw") == 1);
}

// The name written beside timed figures: the kernel's "model name" without its padding, one line.
TEST(CpuModelName, IsTheKernelsModelNameTrimmed) {
  const std::string name = cpu_model_name();
  ASSERT_FALSE(name.empty());
  EXPECT_EQ(name.find('\n'), std::string::npos);
  std::ifstream cpuinfo("/proc/cpuinfo");
  std::string line, expected = "unknown";
  while (std::getline(cpuinfo, line))
    if (line.rfind("model name", 0) == 0) {
      expected = line.substr(line.find(':') + 1);
      expected.erase(0, expected.find_first_not_of(" \t"));
      expected.erase(expected.find_last_not_of(" \t") + 1);
      break;
    }
  EXPECT_EQ(name, expected);
  EXPECT_NE(name.front(), ' ');
  EXPECT_NE(name.back(), ' ');
}

}  // namespace
}  // namespace bsms
