// The tracked along-route position of a vehicle: a Kalman filter over (s, v) with a constant-
// velocity model driven by random acceleration (the vehicle's dynamics), speed limits, and
// gating of each measurement against the prediction, so that one bad measurement cannot move the
// answer further than the vehicle can move between two frames.
#pragma once

#include <Eigen/Core>

namespace epiloc {

struct TrackFilterOptions {
  // Standard deviation of the random acceleration along the route: a car's acceleration and
  // braking in traffic stay within about 3 m/s^2 (emergency braking reaches 8-9).
  double accel_sigma_mps2 = 3.0;
  // Speed limits along the route: no road vehicle exceeds 70 m/s (250 km/h); reversing is slow.
  double max_speed_mps = 70.0;
  double max_reverse_mps = 3.0;
  // Speed uncertainty when tracking starts (the speed is unknown: up to about 30 m/s, 2 sigma).
  double initial_speed_sigma_mps = 15.0;
  // A measurement whose normalised squared innovation exceeds this is refused: the 99.9 %
  // quantile of chi-square with 1 degree of freedom.
  double gate_chi2 = 10.83;

  void Check() const;
};

class AlongTrackFilter {
 public:
  explicit AlongTrackFilter(const TrackFilterOptions& options = TrackFilterOptions());

  bool initialised() const { return initialised_; }
  // Starts tracking at time t from a position measurement (speed unknown, or given).
  void Initialise(double timestamp_s, double s_m, double sigma_m);
  void Initialise(double timestamp_s, double s_m, double sigma_m, double v_mps, double sigma_v_mps);
  void Reset() { initialised_ = false; }

  // Moves the state to time t (no-op for t <= the state's time).
  void Predict(double timestamp_s);
  // Normalised squared innovation of a position measurement against the current state.
  double Innovation2(double s_m, double sigma_m) const;
  bool Accepts(double s_m, double sigma_m) const {
    return Innovation2(s_m, sigma_m) <= options_.gate_chi2;
  }
  // Fuses a position measurement (the caller gates it first); the speed is then clamped to the
  // limits.
  void Update(double s_m, double sigma_m);

  double timestamp_s() const { return t_; }
  double s_m() const { return x_(0); }
  double v_mps() const { return x_(1); }
  double sigma_s_m() const;
  double sigma_v_mps() const;

 private:
  TrackFilterOptions options_;
  bool initialised_ = false;
  double t_ = 0.0;
  Eigen::Vector2d x_ = Eigen::Vector2d::Zero();
  Eigen::Matrix2d p_ = Eigen::Matrix2d::Identity();
};

}  // namespace epiloc
