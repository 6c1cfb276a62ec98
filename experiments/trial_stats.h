// Summaries over repeated trials of an experiment: each trial yields one
// curve (a value per round or checkpoint) and the plots show the mean curve
// with a band of one standard error of that mean.
#ifndef BITEWISE_EXPERIMENTS_TRIAL_STATS_H_
#define BITEWISE_EXPERIMENTS_TRIAL_STATS_H_

#include <vector>

namespace bitewise::experiments {

struct CurveSummary {
  std::vector<double> mean;
  // Sample standard deviation / sqrt(trials); 0 with a single trial.
  std::vector<double> standard_error;
};

// `curves[trial][i]`; every curve must have the same length.
CurveSummary SummarizeCurves(const std::vector<std::vector<double>>& curves);

// Element-wise a - b of two equally long curves.
std::vector<double> Difference(const std::vector<double>& a,
                               const std::vector<double>& b);

}  // namespace bitewise::experiments

#endif  // BITEWISE_EXPERIMENTS_TRIAL_STATS_H_
