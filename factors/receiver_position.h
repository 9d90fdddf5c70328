// Where a radio reading was received, for the RSS and range factors.
//
// A reading at time t between two graph states a and b (times t_a ≤ t ≤ t_b) is received at
// the linearly interpolated position p(t) = (1 − α)·p_a + α·p_b, α = (t − t_a)/(t_b − t_a);
// a reading at a state uses that state alone. Position blocks have kDim = 2 (planar step
// graphs: the receiver is at a fixed height z_r) or kDim = 3 (INS graphs: z from the state).
// The anchor distance d = ‖p − a‖ is softened as √(‖p − a‖² + ε²), ε = 1 mm, so that it stays
// differentiable when the receiver passes under an anchor.
#ifndef WALKGRAPH_FACTORS_RECEIVER_POSITION_H_
#define WALKGRAPH_FACTORS_RECEIVER_POSITION_H_

#include <cmath>

#include <Eigen/Core>

namespace walkgraph::factors_internal {

template <int kDim>
struct Receiver {
  static_assert(kDim == 2 || kDim == 3, "position blocks are planar (2) or 3-D (3)");
  Eigen::Vector3d anchor_m;
  double receiver_height_m = 0.0;  // kDim == 2 only
  double alpha = 0.0;              // weight of p_b (interpolated readings only)

  // Distance to the anchor from p_a alone (p_b == nullptr) or from the interpolation.
  template <typename T>
  T Distance(const T* p_a, const T* p_b) const {
    return DistanceTo(p_a, p_b, static_cast<const T*>(nullptr));
  }
  // The same to an anchor whose horizontal position is a state: (anchor_xy[0], anchor_xy[1],
  // anchor_m.z()); anchor_xy == nullptr: anchor_m.
  template <typename T>
  T DistanceTo(const T* p_a, const T* p_b, const T* anchor_xy) const {
    using std::sqrt;
    T q[3];
    for (int i = 0; i < kDim; ++i) {
      q[i] = p_b == nullptr ? p_a[i] : T(1.0 - alpha) * p_a[i] + T(alpha) * p_b[i];
    }
    if (kDim == 2) q[2] = T(receiver_height_m);
    const T ax = anchor_xy == nullptr ? T(anchor_m.x()) : anchor_xy[0];
    const T ay = anchor_xy == nullptr ? T(anchor_m.y()) : anchor_xy[1];
    const T dx = q[0] - ax, dy = q[1] - ay, dz = q[2] - T(anchor_m.z());
    return sqrt(dx * dx + dy * dy + dz * dz + T(1e-6));
  }
};

}  // namespace walkgraph::factors_internal

#endif  // WALKGRAPH_FACTORS_RECEIVER_POSITION_H_
