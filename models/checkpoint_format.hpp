// The checkpoint file's identity, without LibTorch: programs that only recognise a checkpoint (the
// bsms front end's info) include this rather than checkpoint.hpp.
#pragma once

namespace bsms {

// The root format attribute of checkpoint files (checkpoint.hpp).
inline constexpr const char* kCheckpointFormat = "bsms-checkpoint";

}  // namespace bsms
