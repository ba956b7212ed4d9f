# Crash safety of `bsms train`: >= 24 kill -9 at pseudo-random moments (some inside checkpoint
# writes), each followed by --resume; the finished run must equal an uninterrupted one bit for bit
# (tests/cli/crash_resume.sh). Included from tests/cli/CMakeLists.txt.
add_test(NAME cli.train_crash_resume
  COMMAND ${CMAKE_CURRENT_LIST_DIR}/crash_resume.sh $<TARGET_FILE:bsms> ${PROJECT_SOURCE_DIR}
          ${CMAKE_CURRENT_BINARY_DIR}/crash_resume 13 24)
set_tests_properties(cli.train_crash_resume PROPERTIES TIMEOUT 600 COST 60)
