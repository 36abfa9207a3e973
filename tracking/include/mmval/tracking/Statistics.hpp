// Two-sample statistics for comparing distributions (speeds, step lengths).
#pragma once
#include <vector>

namespace mmval::tracking {

/// Wasserstein-1 (earth mover's) distance between two empirical
/// distributions: the integral of |F_a(x) - F_b(x)| dx.
double wasserstein1(std::vector<double> a, std::vector<double> b);

struct KsResult {
  double statistic = 0;  ///< sup |F_a - F_b|
  double p_value = 1;    ///< asymptotic Kolmogorov distribution
};

/// Two-sample Kolmogorov-Smirnov test. The p-value uses the asymptotic
/// Kolmogorov series with Stephens' small-sample correction of the argument,
/// lambda = (sqrt(n_e) + 0.12 + 0.11 / sqrt(n_e)) D, n_e = n_a n_b / (n_a + n_b).
KsResult kolmogorovSmirnov(std::vector<double> a, std::vector<double> b);

/// Q_KS(lambda) = 2 sum_{j>=1} (-1)^(j-1) exp(-2 j^2 lambda^2).
double kolmogorovQ(double lambda);

double mean(const std::vector<double>& v);
double median(std::vector<double> v);
/// Population standard deviation, sqrt(sum (x - mean)^2 / N) (the paper's Eq. 18).
double populationStd(const std::vector<double>& v);

}  // namespace mmval::tracking
