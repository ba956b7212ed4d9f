// main() of the test executables that train models: the process environment the bsms executable
// runs in (core/runtime.hpp ensure_process_environment: libgomp's wait policy, OpenBLAS's vector
// kernels where its own detection falls back to SSE3, glibc's malloc on huge pages), so that
// in-process trainings run as they do under `bsms train`, then GoogleTest.
#include <gtest/gtest.h>

#include "core/runtime.hpp"

int main(int argc, char** argv) {
  bsms::ensure_process_environment(argv);
  ::testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
