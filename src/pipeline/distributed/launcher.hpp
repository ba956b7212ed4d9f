// `bsms train --nproc N`: the local process launcher. Starts this executable as N ranks with
// torchrun's environment variables set (the ranks then join through distributed.hpp), forwards
// SIGINT and SIGTERM to them, and stops the group when one rank fails.
#pragma once

#include <string>
#include <vector>

namespace bsms {

// Runs this executable (argv, with the launcher's options removed by the caller) as N ranks with
// torchrun's variables set: ranks NODE_RANK*N .. NODE_RANK*N+N-1 of WORLD_SIZE (default N),
// MASTER_PORT a free port when unset on a single machine. Waits for all; when one fails, the
// others get `grace_s` to stop by themselves before they are killed. Returns the exit code: 0, or
// the first failing rank's code (5 for a rank killed by a signal), after one line that names that
// rank.
int launch_local_ranks(const std::vector<std::string>& argv, int nproc, double grace_s);

}  // namespace bsms
