// The model of 002's filters (internal to filters/prieto.cc and its test): the nominal state and
// its error-state layout, retraction, propagation and process noise, and the measurement models
// (IMU as measurements, stance evidences, RSS and TOA); the equations are in
// walkgraph/filters/prieto.h's opening comment.
#ifndef WALKGRAPH_SRC_FILTERS_PRIETO_MODEL_H_
#define WALKGRAPH_SRC_FILTERS_PRIETO_MODEL_H_

#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "walkgraph/filters/prieto.h"

namespace walkgraph::prieto {

// Error-state layout. The radio-only variant uses the first kKinematicDim components.
inline constexpr int kPos = 0, kVel = 3, kAcc = 6, kAtt = 9, kOmega = 12, kAccBias = 15,
                     kGyroBias = 18;
inline constexpr int kFullDim = 21, kKinematicDim = 9;

struct NominalState {
  Eigen::Vector3d x = Eigen::Vector3d::Zero();
  Eigen::Vector3d v = Eigen::Vector3d::Zero();
  Eigen::Vector3d a = Eigen::Vector3d::Zero();
  Eigen::Quaterniond q_nb = Eigen::Quaterniond::Identity();  // body→nav; paper's q̄ = q_nb⁻¹
  Eigen::Vector3d w = Eigen::Vector3d::Zero();               // body rate ω
  Eigen::Vector3d b_f = Eigen::Vector3d::Zero();
  Eigen::Vector3d b_w = Eigen::Vector3d::Zero();
};

// y ⊞ δ (δ of size kKinematicDim or kFullDim; the attitude is renormalized).
NominalState Retract(const NominalState& y, const Eigen::Ref<const Eigen::VectorXd>& delta);
// to ⊟ from, of size dim (LocalInto: into d, of the size wanted).
Eigen::VectorXd Local(const NominalState& from, const NominalState& to, int dim);
void LocalInto(const NominalState& from, const NominalState& to, Eigen::Ref<Eigen::VectorXd> d);

// Mean of the dynamic model over Δ = dt (eq. 1, 3, 4).
NominalState Propagate(const NominalState& y, double dt);
// F = ∂(Propagate(y ⊞ δ) ⊟ Propagate(y))/∂δ at δ = 0 (dim × dim).
Eigen::MatrixXd TransitionJacobian(const NominalState& y, double dt, int dim);
// Q over one step of dt in error coordinates (dim × dim), Sec. IV-A values (radio-only
// kKinematicDim: no noise on the vertical axis).
Eigen::MatrixXd ProcessNoise(const PrietoOptions& options, double dt, int dim);
// Reset Jacobian G after injecting δ (identity but I − ½[δθ]× on the attitude block).
Eigen::MatrixXd ResetJacobian(const Eigen::VectorXd& delta);

enum class MeasurementKind {
  kImu,        // [z^f z^ω] (eq. 7–8)
  kImuStance,  // [z^f z^ω 0 0 0] (eq. 7–9)
  kRss,        // eq. 5
  kToa,        // eq. 6
  kStack,      // the rows of `parts` stacked (a radio epoch: z^s and z^τ as vectors)
};

struct Measurement {
  MeasurementKind kind = MeasurementKind::kImu;
  Eigen::VectorXd z;
  Eigen::MatrixXd R;
  Eigen::Vector3d anchor_m = Eigen::Vector3d::Zero();  // kRss, kToa
  std::vector<Measurement> parts;                      // kStack
};

// Stacks measurements into one (z and R block-diagonal).
Measurement StackMeasurements(std::vector<Measurement> parts);

// Constants of the measurement functions.
struct MeasurementParams {
  double gravity_mps2 = 9.81;
  double rss_alpha_dbm = -40.0, rss_beta = 3.0, rss_d0_m = 1.0;
  double rss_sign = 1.0;  // PathLossModel::sign(): +1 dBm, −1 RFCode units
  double toa_alpha_m = 0.0, toa_beta = 1.0;
  double receiver_offset_z_m = 0.0;
};

// h(y) of a measurement (eq. 5–9).
Eigen::VectorXd PredictMeasurement(const MeasurementParams& params, const Measurement& m,
                                   const NominalState& y);
// H = ∂h(y ⊞ δ)/∂δ at δ = 0 (rows × dim).
Eigen::MatrixXd MeasurementJacobian(const MeasurementParams& params, const Measurement& m,
                                    const NominalState& y, int dim);

// Planar output: (x, y, heading of the IMU's x axis) and its covariance from the error
// covariance P (radio-only: heading of the velocity).
struct PlanarPose {
  Eigen::Vector3d pose = Eigen::Vector3d::Zero();
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity();
};
PlanarPose ToPlanarPose(const NominalState& y, const Eigen::MatrixXd& P);

}  // namespace walkgraph::prieto

#endif  // WALKGRAPH_SRC_FILTERS_PRIETO_MODEL_H_
