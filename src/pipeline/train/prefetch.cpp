#include "pipeline/train/prefetch.hpp"

#include <set>

namespace bsms {

Prefetcher::Prefetcher(const Dataset& data, GraphStore& store,
                       std::function<std::vector<int64_t>(int64_t)> trajectories, int64_t lookahead)
    : data_(data), store_(store), trajectories_(std::move(trajectories)), lookahead_(lookahead) {
  if (lookahead_ > 0) thread_ = std::thread([this] { run(); });
}

Prefetcher::~Prefetcher() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void Prefetcher::reached(int64_t position) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    reached_ = std::max(reached_, position);
  }
  wake_.notify_all();
}

int64_t Prefetcher::batches_done() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return next_;
}

void Prefetcher::run() {
  const std::string field = data_.fields().empty() ? std::string() : data_.fields()[0].name;
  std::set<int64_t> read;  // trajectories whose first read is done
  for (;;) {
    int64_t position;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      wake_.wait(lock, [&] { return stop_ || next_ <= reached_ + lookahead_; });
      if (stop_) return;
      position = next_;
    }
    try {
      for (int64_t t : trajectories_(position)) {
        const TrajectoryMesh& mesh = data_.mesh(t);
        store_.get(mesh);
        if (!field.empty() && read.insert(t).second) data_.read(t, field, 0, 1);
      }
    } catch (...) {
      return;  // the training thread meets the same error at this sample and reports it
    }
    std::lock_guard<std::mutex> lock(mutex_);
    next_ = position + 1;
  }
}

}  // namespace bsms
