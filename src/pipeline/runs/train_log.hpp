// RUN/train_log.csv (docs/design.md "Runs"): one row per optimizer step, as a type with one writer
// (bsms train appends rows) and one strict reader (bsms report's loss plots; resume keeps the
// rows up to the checkpoint). Columns: step, wall_s, loss, valid_loss, valid_zero_prediction, lr;
// the two validation cells are empty on steps without validation.
#pragma once

#include <cmath>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace bsms {

inline constexpr const char* kTrainLogHeader =
    "step,wall_s,loss,valid_loss,valid_zero_prediction,lr";

struct TrainLogRow {
  int64_t step = 0;
  double wall_s = 0.0;  // training time of the run so far (all sessions)
  double loss = 0.0;
  double valid_loss = std::nan("");             // NaN: no validation at this step
  double valid_zero_prediction = std::nan("");  // the loss of predicting zero on the same frames
  double lr = 0.0;
  bool has_valid() const { return std::isfinite(valid_loss); }
};

// The row as written to the file, without the newline.
std::string format_train_log_row(const TrainLogRow& row);
// A whole row of the current layout, or none (the header, a torn or malformed line).
std::optional<TrainLogRow> parse_train_log_row(const std::string& line);
// Every row of a log. An unterminated last line (a session killed mid-write, or one still
// writing) is left out; a missing file, an unknown header or a malformed row is an InputError
// naming the file (and the line).
std::vector<TrainLogRow> read_train_log(const std::string& file);

// Per row, the mean of the finite training losses among the last `window` rows (itself
// included; NaN where there is none): the curve bsms report plots, since per-step losses of a
// batch of 1-2 scatter over a decade. `window` 0 is taken as 1.
std::vector<double> trailing_mean_loss(const std::vector<TrainLogRow>& rows, size_t window);
// The same over any values: per index, the mean of the finite values among the last `window`.
std::vector<double> trailing_mean(const std::vector<double>& values, size_t window);

// One validation check as bsms report compares runs: the loss as a fraction of predicting zero
// on the same frames (runs that validate on different frames, e.g. other seeds, compare by it).
struct ValidationPoint {
  int64_t step = 0;
  double wall_s = 0.0;
  double fraction = 0.0;  // valid_loss / valid_zero_prediction
};

// The checks of a log that carry both the loss and its zero-prediction reference, in order.
std::vector<ValidationPoint> validation_curve(const std::vector<TrainLogRow>& rows);

// Where a run ends: the mean fraction of its last `window` checks (fewer if it has fewer; NaN
// if none). `window` 0 is taken as 1.
double final_validation(const std::vector<ValidationPoint>& curve, size_t window);

// The first check at which the mean fraction of the last `window` checks (itself included) is at
// or below `target`: when a run has reached that loss, read with the same smoothing that sets
// final_validation. None before `window` checks exist, or if it never gets there.
std::optional<ValidationPoint> first_reaching(const std::vector<ValidationPoint>& curve,
                                              double target, size_t window);

}  // namespace bsms
