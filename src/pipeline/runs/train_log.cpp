#include "pipeline/runs/train_log.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include "core/config.hpp"
#include "core/error.hpp"

namespace bsms {

namespace {

std::vector<std::string> split_cells(const std::string& line) {
  std::vector<std::string> cells;
  size_t start = 0;
  for (;;) {
    const size_t comma = line.find(',', start);
    cells.push_back(line.substr(start, comma == std::string::npos ? comma : comma - start));
    if (comma == std::string::npos) return cells;
    start = comma + 1;
  }
}

std::optional<int64_t> parse_step(const std::string& cell) {
  if (cell.empty() || cell.size() > 18 ||
      !std::all_of(cell.begin(), cell.end(), [](char c) { return c >= '0' && c <= '9'; }))
    return std::nullopt;
  return std::stoll(cell);
}

// A whole cell as a number ("nan" and "inf" as written by the stream included).
std::optional<double> parse_number(const std::string& cell) {
  if (cell.empty()) return std::nullopt;
  char* end = nullptr;
  const double value = std::strtod(cell.c_str(), &end);
  if (end != cell.c_str() + cell.size()) return std::nullopt;
  return value;
}

// Cells of one row.
std::optional<TrainLogRow> parse_cells(const std::vector<std::string>& cells) {
  if (cells.size() != 6u) return std::nullopt;
  TrainLogRow row;
  const auto step = parse_step(cells[0]);
  const auto wall = parse_number(cells[1]);
  const auto loss = parse_number(cells[2]);
  const auto lr = parse_number(cells.back());
  if (!step || !wall || !loss || !lr) return std::nullopt;
  // Times and learning rates are finite and >= 0; a loss is >= 0 or not finite (a diverged
  // step is logged as it was).
  const auto loss_like = [](double v) { return std::isnan(v) || v >= 0.0; };
  if (!std::isfinite(*wall) || *wall < 0.0 || !std::isfinite(*lr) || *lr < 0.0 || !loss_like(*loss))
    return std::nullopt;
  row.step = *step;
  row.wall_s = *wall;
  row.loss = *loss;
  row.lr = *lr;
  const std::string& valid = cells[3];
  const std::string& zero = cells[4];
  if (!valid.empty()) {
    const auto v = parse_number(valid);
    if (!v || !loss_like(*v)) return std::nullopt;
    row.valid_loss = *v;
  }
  if (!zero.empty()) {
    const auto z = parse_number(zero);
    if (!z || valid.empty() || !loss_like(*z)) return std::nullopt;
    row.valid_zero_prediction = *z;
  }
  return row;
}

}  // namespace

std::string format_train_log_row(const TrainLogRow& row) {
  std::ostringstream out;
  out.precision(6);
  out << row.step << ',' << row.wall_s << ',' << row.loss << ',';
  if (row.has_valid())
    out << row.valid_loss << ',' << row.valid_zero_prediction;
  else
    out << ',';
  out << ',' << row.lr;
  return out.str();
}

std::optional<TrainLogRow> parse_train_log_row(const std::string& line) {
  return parse_cells(split_cells(line));
}

std::vector<TrainLogRow> read_train_log(const std::string& file) {
  require_regular_file(file, "training log");  // a FIFO or a device would block or never end
  std::ifstream in(file, std::ios::binary);
  if (!in) throw InputError(file + ": cannot open the training log (written by bsms train)");
  std::string line;
  if (!std::getline(in, line) || line != kTrainLogHeader)
    throw InputError(file + ": line 1 is not a training-log header (expected " +
                     std::string(kTrainLogHeader) + ")");
  std::vector<TrainLogRow> rows;
  for (int64_t number = 2; std::getline(in, line); ++number) {
    if (in.eof()) break;  // no newline after it: torn, or still being written
    const auto row = parse_cells(split_cells(line));
    if (!row)
      throw InputError(file + ": line " + std::to_string(number) + " is not a log row (" +
                       std::string(kTrainLogHeader) + "): " + line.substr(0, 80));
    rows.push_back(*row);
  }
  return rows;
}

std::vector<double> trailing_mean(const std::vector<double>& values, size_t window) {
  window = std::max<size_t>(window, 1);
  std::vector<double> mean(values.size());
  double sum = 0.0;
  size_t finite = 0;
  for (size_t k = 0; k < values.size(); ++k) {
    if (std::isfinite(values[k])) {
      sum += values[k];
      ++finite;
    }
    if (k >= window && std::isfinite(values[k - window])) {
      sum -= values[k - window];
      --finite;
    }
    mean[k] = finite ? sum / static_cast<double>(finite) : std::nan("");
  }
  return mean;
}

std::vector<double> trailing_mean_loss(const std::vector<TrainLogRow>& rows, size_t window) {
  std::vector<double> losses;
  losses.reserve(rows.size());
  for (const TrainLogRow& row : rows) losses.push_back(row.loss);
  return trailing_mean(losses, window);
}

std::vector<ValidationPoint> validation_curve(const std::vector<TrainLogRow>& rows) {
  std::vector<ValidationPoint> curve;
  for (const TrainLogRow& row : rows)
    if (row.has_valid() && std::isfinite(row.valid_zero_prediction) &&
        row.valid_zero_prediction > 0.0)
      curve.push_back({row.step, row.wall_s, row.valid_loss / row.valid_zero_prediction});
  return curve;
}

namespace {

std::vector<double> fractions(const std::vector<ValidationPoint>& curve) {
  std::vector<double> f;
  f.reserve(curve.size());
  for (const ValidationPoint& p : curve) f.push_back(p.fraction);
  return f;
}

}  // namespace

double final_validation(const std::vector<ValidationPoint>& curve, size_t window) {
  return curve.empty() ? std::nan("") : trailing_mean(fractions(curve), window).back();
}

std::optional<ValidationPoint> first_reaching(const std::vector<ValidationPoint>& curve,
                                              double target, size_t window) {
  window = std::max<size_t>(window, 1);
  const std::vector<double> mean = trailing_mean(fractions(curve), window);
  // Compared with a relative tolerance against a target summed in another order.
  for (size_t k = window - 1; k < curve.size(); ++k)
    if (mean[k] <= target * (1.0 + 1e-12)) return curve[k];
  return std::nullopt;
}

}  // namespace bsms
