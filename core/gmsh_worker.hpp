// The gmsh worker: bsms reads every file it gives the gmsh library (a .geo script, CAD, the mesh
// formats the direct MSH reader leaves to gmsh) in a child process, `bsms-gmsh-worker` (built next
// to `bsms`), never in its own. A .geo file is a program: gmsh can loop forever in it, allocate
// without bound, end the process (Exit) or run shell commands (SystemCall). In the child, a loop
// or an Exit ends the child, not bsms, under limits bsms sets; the mesh comes back through an
// anonymous file (gmsh_result.hpp) and bsms reports any other outcome in one line naming the file.
//
// Why a helper executable rather than fork(): bsms may hold LibTorch and OpenMP thread pools when
// it reads a mesh (simulate, generate), and a fork of a threaded process keeps only the calling
// thread, so locks held by the others and the OpenMP runtime's pool stay broken in the child;
// gmsh's meshers use OpenMP. posix_spawn of a fresh executable starts from a clean process and is
// safe from any thread. It costs the start of one process (measured in docs/hardening.md).
//
// The child: stdin /dev/null (gmsh never waits for an answer), stdout discarded, stderr kept for
// the last line of a crash, its own process group (killed whole at the end, so programs a script
// started with --allow-geo-commands do not outlive it), killed when bsms dies (PR_SET_PDEATHSIG),
// no core dump, RLIMIT_AS = the memory limit, RLIMIT_CPU as a backstop of the wall-clock limit that
// bsms enforces itself (SIGKILL of the group). Without --allow-geo-commands it also installs a
// seccomp filter before gmsh starts: no execve, no opening a file for writing, no creating,
// removing, renaming or re-permissioning files, no sockets.
#pragma once

#include <string>

namespace bsms {

struct GmshLimits {
  double time_limit_s = 120.0;      // wall-clock seconds for one file (reading and meshing)
  double memory_limit_gib = 0.0;    // the worker's address space in GiB; 0: default_gmsh_memory_gib
  bool allow_geo_commands = false;  // run what geo_scan refuses; the user's risk
};

// Half the machine's physical memory, at least 1 GiB.
double default_gmsh_memory_gib();

// The defaults, overridden by BSMS_GEO_TIME_LIMIT (seconds) and BSMS_GEO_MEMORY_LIMIT (GiB) when
// set; InputError naming the variable when one is not a number > 0.
GmshLimits gmsh_limits_from_environment();

// The limits read_mesh_with_gmsh applies from now on, process-wide (the CLI sets them from its
// options before any work). Until set, gmsh_limits_from_environment() at the first use.
void set_gmsh_limits(const GmshLimits& limits);
GmshLimits gmsh_limits();

// The worker executable: $BSMS_GMSH_WORKER, else bsms-gmsh-worker next to the running executable,
// else the one this build made.
std::string gmsh_worker_path();

}  // namespace bsms
