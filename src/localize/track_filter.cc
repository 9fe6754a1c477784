#include "epiloc/localize/track_filter.h"

#include <algorithm>
#include <cmath>

#include "epiloc/core/error.h"

namespace epiloc {

void TrackFilterOptions::Check() const {
  EPILOC_CHECK(accel_sigma_mps2 > 0, "track filter: accel_sigma_mps2 must be > 0");
  EPILOC_CHECK(max_speed_mps > 0, "track filter: max_speed_mps must be > 0");
  EPILOC_CHECK(max_reverse_mps >= 0, "track filter: max_reverse_mps must be >= 0");
  EPILOC_CHECK(initial_speed_sigma_mps > 0, "track filter: initial_speed_sigma_mps must be > 0");
  EPILOC_CHECK(gate_chi2 > 0, "track filter: gate_chi2 must be > 0");
}

AlongTrackFilter::AlongTrackFilter(const TrackFilterOptions& options) : options_(options) {
  options_.Check();
}

void AlongTrackFilter::Initialise(double timestamp_s, double s_m, double sigma_m) {
  Initialise(timestamp_s, s_m, sigma_m, 0.0, options_.initial_speed_sigma_mps);
}

void AlongTrackFilter::Initialise(
    double timestamp_s, double s_m, double sigma_m, double v_mps, double sigma_v_mps) {
  EPILOC_CHECK(sigma_m > 0 && sigma_v_mps > 0, "track filter: sigmas must be > 0");
  initialised_ = true;
  t_ = timestamp_s;
  x_ << s_m, v_mps;
  p_ << sigma_m * sigma_m, 0.0, 0.0, sigma_v_mps * sigma_v_mps;
}

void AlongTrackFilter::Predict(double timestamp_s) {
  EPILOC_CHECK(initialised_, "track filter: Predict before Initialise");
  const double dt = timestamp_s - t_;
  if (!(dt > 0)) return;
  Eigen::Matrix2d f;
  f << 1.0, dt, 0.0, 1.0;
  // Random acceleration, white over the interval: the usual continuous-white-noise model.
  const double q = options_.accel_sigma_mps2 * options_.accel_sigma_mps2;
  Eigen::Matrix2d process;
  process << dt * dt * dt / 3.0, dt * dt / 2.0, dt * dt / 2.0, dt;
  x_ = f * x_;
  p_ = f * p_ * f.transpose() + q * process;
  t_ = timestamp_s;
}

double AlongTrackFilter::Innovation2(double s_m, double sigma_m) const {
  const double innovation = s_m - x_(0);
  return innovation * innovation / (p_(0, 0) + sigma_m * sigma_m);
}

void AlongTrackFilter::Update(double s_m, double sigma_m) {
  EPILOC_CHECK(initialised_, "track filter: Update before Initialise");
  const double s = p_(0, 0) + sigma_m * sigma_m;
  const Eigen::Vector2d k = p_.col(0) / s;
  x_ += k * (s_m - x_(0));
  p_ -= k * p_.row(0);
  p_ = 0.5 * (p_ + p_.transpose());
  x_(1) = std::clamp(x_(1), -options_.max_reverse_mps, options_.max_speed_mps);
}

double AlongTrackFilter::sigma_s_m() const { return std::sqrt(std::max(0.0, p_(0, 0))); }
double AlongTrackFilter::sigma_v_mps() const { return std::sqrt(std::max(0.0, p_(1, 1))); }

}  // namespace epiloc
