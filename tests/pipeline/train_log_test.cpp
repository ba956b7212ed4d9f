// RUN/train_log.csv (pipeline/runs/train_log.hpp): rows written by the trainer's formatter read
// back unchanged; a torn last line is left out, a malformed row is one InputError naming the file
// and the line; a log in another layout is refused; the plotted trailing mean of the loss equals
// the mean computed window by window.
#include "pipeline/runs/train_log.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "tests/temp_dir.hpp"

namespace bsms {
namespace {

namespace fs = std::filesystem;

// This test process's own folder, emptied by each test at its end.
fs::path log_dir() {
  static const fs::path dir = testing::unique_temp_dir("train_log");
  return dir;
}

std::string temp_log(const std::string& name, const std::string& text) {
  const fs::path dir = log_dir();
  fs::create_directories(dir);
  const fs::path file = dir / name;
  std::ofstream(file, std::ios::binary) << text;
  return file.string();
}

std::string error_of(const std::string& file) {
  try {
    read_train_log(file);
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

TEST(TrainLogFile, RowsRoundTripAndTornLinesAreLeftOut) {
  TrainLogRow plain;
  plain.step = 1;
  plain.wall_s = 0.093673;
  plain.loss = 1.81095;
  plain.lr = 1.99e-05;
  TrainLogRow checked = plain;
  checked.step = 2;
  checked.valid_loss = 0.327;
  checked.valid_zero_prediction = 0.460242;
  EXPECT_EQ(format_train_log_row(plain), "1,0.093673,1.81095,,,1.99e-05");
  EXPECT_EQ(format_train_log_row(checked), "2,0.093673,1.81095,0.327,0.460242,1.99e-05");
  const std::string file =
      temp_log("log.csv", std::string(kTrainLogHeader) + "\n" + format_train_log_row(plain) + "\n" +
                              format_train_log_row(checked) + "\n3,0.2,1.5,,");  // torn
  const auto rows = read_train_log(file);
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_FALSE(rows[0].has_valid());
  EXPECT_TRUE(std::isnan(rows[0].valid_zero_prediction));
  EXPECT_EQ(rows[1].step, 2);
  EXPECT_DOUBLE_EQ(rows[1].valid_loss, 0.327);
  EXPECT_DOUBLE_EQ(rows[1].valid_zero_prediction, 0.460242);
  EXPECT_DOUBLE_EQ(rows[1].lr, 1.99e-05);
  // The resume filter: whole rows only.
  EXPECT_TRUE(parse_train_log_row(format_train_log_row(checked)).has_value());
  EXPECT_FALSE(parse_train_log_row(kTrainLogHeader).has_value());
  EXPECT_FALSE(parse_train_log_row("3,0.2,1.5,,").has_value());
  EXPECT_FALSE(
      parse_train_log_row("3,0.2,1.5,,0.4,0.001").has_value());  // zero prediction, no loss
  EXPECT_FALSE(parse_train_log_row("-3,0.2,1.5,,,0.001").has_value());

  // A log in another layout (no zero-prediction column) is refused by its header.
  EXPECT_NE(error_of(temp_log("other.csv", "step,wall_s,loss,valid_loss,lr\n1,0.1,2.0,,0.001\n"))
                .find("other.csv: line 1 is not a training-log header"),
            std::string::npos);
  fs::remove_all(log_dir());
}

TEST(TrainLogFile, BadLogsNameTheFileAndLine) {
  const std::string header = std::string(kTrainLogHeader) + "\n";
  EXPECT_NE(error_of(temp_log("bad_row.csv", header + "1,0.1,2.0,,,0.001\n2,soon,1.9,,,0.001\n"))
                .find("bad_row.csv: line 3 is not a log row"),
            std::string::npos);
  EXPECT_NE(error_of(temp_log("short.csv", header + "1,0.1,2.0,0.001\n")).find("line 2"),
            std::string::npos);
  EXPECT_NE(error_of(temp_log("header.csv", "step;loss\n1;2\n")).find("header.csv: line 1"),
            std::string::npos);
  EXPECT_NE(error_of("/nonexistent/train_log.csv").find("/nonexistent/train_log.csv"),
            std::string::npos);
  EXPECT_EQ(error_of(temp_log("empty_rows.csv", header)), "no error");
  fs::remove_all(log_dir());
}

// The report's training-loss curve against a brute-force mean over each window, with NaN losses
// (a diverged step) skipped and a window holding only NaN giving NaN.
TEST(TrainLogFile, TrailingMeanLossEqualsTheMeanOfEachWindow) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> loss(0.01, 3.0);
  std::vector<TrainLogRow> rows(500);
  for (size_t k = 0; k < rows.size(); ++k) {
    rows[k].step = static_cast<int64_t>(k + 1);
    rows[k].loss = (k % 37 == 5 || (k >= 200 && k < 204)) ? std::nan("") : loss(rng);
  }
  for (size_t window : {1u, 3u, 4u, 50u, 1000u}) {
    const std::vector<double> mean = trailing_mean_loss(rows, window);
    ASSERT_EQ(mean.size(), rows.size());
    for (size_t k = 0; k < rows.size(); ++k) {
      double sum = 0.0;
      int finite = 0;
      for (size_t i = k + 1 > window ? k + 1 - window : 0; i <= k; ++i)
        if (std::isfinite(rows[i].loss)) {
          sum += rows[i].loss;
          ++finite;
        }
      if (finite == 0) {
        EXPECT_TRUE(std::isnan(mean[k])) << "window " << window << ", row " << k;
      } else {
        EXPECT_NEAR(mean[k], sum / finite, 1e-9) << "window " << window << ", row " << k;
      }
    }
  }
  EXPECT_TRUE(std::isnan(trailing_mean_loss(rows, 4)[203]));       // rows 200-203 are all NaN
  EXPECT_DOUBLE_EQ(trailing_mean_loss(rows, 0)[0], rows[0].loss);  // window 0 acts as 1
  EXPECT_TRUE(trailing_mean_loss({}, 5).empty());
}

// The report's training-cost table: the validation curve keeps only checks with a reference, a
// run's final loss is the mean of its last checks, and the first check reaching a loss matches a
// brute-force scan of every window, on many random curves.
TEST(TrainLogFile, FirstReachingMatchesABruteForceScan) {
  std::vector<TrainLogRow> rows(6);
  for (size_t k = 0; k < rows.size(); ++k) {
    rows[k].step = static_cast<int64_t>(k + 1);
    rows[k].wall_s = 10.0 * static_cast<double>(k + 1);
  }
  rows[1].valid_loss = 0.2;
  rows[1].valid_zero_prediction = 0.4;
  rows[3].valid_loss = 0.1;  // no zero-prediction loss beside it: not comparable
  rows[4].valid_loss = 0.1;
  rows[4].valid_zero_prediction = 0.5;
  const std::vector<ValidationPoint> two = validation_curve(rows);
  ASSERT_EQ(two.size(), 2u);
  EXPECT_EQ(two[0].step, 2);
  EXPECT_DOUBLE_EQ(two[0].wall_s, 20.0);
  EXPECT_DOUBLE_EQ(two[0].fraction, 0.5);
  EXPECT_DOUBLE_EQ(two[1].fraction, 0.2);
  EXPECT_DOUBLE_EQ(final_validation(two, 5), 0.35);  // fewer checks than the window
  EXPECT_DOUBLE_EQ(final_validation(two, 1), 0.2);
  EXPECT_DOUBLE_EQ(final_validation(two, 0), 0.2);
  EXPECT_TRUE(std::isnan(final_validation({}, 5)));
  EXPECT_FALSE(first_reaching(two, 1.0, 5).has_value());  // never 5 checks
  ASSERT_TRUE(first_reaching(two, 0.35, 2).has_value());
  EXPECT_EQ(first_reaching(two, 0.35, 2)->step, 5);

  std::mt19937 rng(11);
  std::uniform_real_distribution<double> noise(-0.05, 0.05);
  for (int trial = 0; trial < 200; ++trial) {
    std::vector<ValidationPoint> curve(1 + trial % 40);
    for (size_t k = 0; k < curve.size(); ++k)
      curve[k] = {static_cast<int64_t>(1000 * (k + 1)), 7.5 * static_cast<double>(k + 1),
                  0.8 / (1.0 + 0.2 * static_cast<double>(k)) + noise(rng)};
    for (size_t window : {1u, 3u, 5u}) {
      // A run reaches its own final loss, at its last check or before it.
      const double own = final_validation(curve, window);
      if (curve.size() >= window) {
        const auto self = first_reaching(curve, own, window);
        ASSERT_TRUE(self.has_value()) << "trial " << trial << ", window " << window;
        EXPECT_LE(self->step, curve.back().step);
      }
      for (double target : {0.1, 0.2, 0.3, 0.5, own}) {
        std::optional<int64_t> brute;
        for (size_t k = window - 1; k < curve.size() && !brute; ++k) {
          double sum = 0.0;
          for (size_t i = k + 1 - window; i <= k; ++i) sum += curve[i].fraction;
          if (sum / static_cast<double>(window) <= target * (1.0 + 1e-12)) brute = curve[k].step;
        }
        const auto found = first_reaching(curve, target, window);
        ASSERT_EQ(found.has_value(), brute.has_value())
            << "trial " << trial << ", window " << window << ", target " << target;
        if (found) {
          EXPECT_EQ(found->step, *brute);
        }
      }
    }
  }
}

}  // namespace
}  // namespace bsms
