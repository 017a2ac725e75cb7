#include "lshloc/slam/pose_graph.hpp"

#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <array>
#include <cmath>
#include <string>

#include "lshloc/common/error.hpp"

namespace lshloc {

namespace {

/// Residual of an edge at poses a, b: the measured motion's frame error,
/// e = [R_z^T (R_a^T (t_b - t_a) - t_z); wrap(theta_b - theta_a - theta_z)],
/// with its Jacobians with respect to a and b.
struct Linearized {
  Eigen::Vector3d e;
  Eigen::Matrix3d A;  ///< de/da
  Eigen::Matrix3d B;  ///< de/db
};

Linearized linearize(const Pose2& a, const Pose2& b, const Pose2& z) {
  const double ca = std::cos(a.theta), sa = std::sin(a.theta);
  const double cz = std::cos(z.theta), sz = std::sin(z.theta);
  Eigen::Matrix2d Ra_t, Rz_t, dRa_t;
  Ra_t << ca, sa, -sa, ca;
  Rz_t << cz, sz, -sz, cz;
  dRa_t << -sa, ca, -ca, -sa;  // d(R_a^T)/d(theta_a)
  const Eigen::Vector2d dt(b.x - a.x, b.y - a.y);
  Linearized l;
  l.e.head<2>() = Rz_t * (Ra_t * dt - Eigen::Vector2d(z.x, z.y));
  l.e(2) = wrap_angle(b.theta - a.theta - z.theta);
  l.A.setZero();
  l.B.setZero();
  l.A.topLeftCorner<2, 2>() = -Rz_t * Ra_t;
  l.A.block<2, 1>(0, 2) = Rz_t * dRa_t * dt;
  l.A(2, 2) = -1.0;
  l.B.topLeftCorner<2, 2>() = Rz_t * Ra_t;
  l.B(2, 2) = 1.0;
  return l;
}

}  // namespace

Eigen::Matrix3d diagonal_information(double sigma_xy, double sigma_theta) {
  Eigen::Matrix3d m = Eigen::Matrix3d::Zero();
  m(0, 0) = m(1, 1) = 1.0 / (sigma_xy * sigma_xy);
  m(2, 2) = 1.0 / (sigma_theta * sigma_theta);
  return m;
}

void PoseGraphConfig::validate() const {
  require(max_iterations >= 1, "PoseGraphConfig.max_iterations", ">= 1", max_iterations);
  require(converged_step > 0.0, "PoseGraphConfig.converged_step", "> 0", converged_step);
  require(robust_scale > 0.0, "PoseGraphConfig.robust_scale", "> 0", robust_scale);
}

PoseGraph::PoseGraph(PoseGraphConfig config) : config_((config.validate(), config)) {}

std::uint32_t PoseGraph::add_node(const Pose2& initial) {
  if (!is_finite(initial)) throw Error("PoseGraph::add_node: the initial pose is not finite");
  poses_.push_back(initial);
  stats_.nodes = poses_.size();
  return static_cast<std::uint32_t>(poses_.size() - 1);
}

void PoseGraph::add_edge(const PoseGraphEdge& edge) {
  if (edge.from >= poses_.size() || edge.to >= poses_.size()) {
    throw Error("PoseGraph::add_edge: edge " + std::to_string(edge.from) + " -> " + std::to_string(edge.to) +
                " names a node that does not exist (" + std::to_string(poses_.size()) + " nodes)");
  }
  if (edge.from == edge.to) throw Error("PoseGraph::add_edge: an edge must join two different nodes");
  if (!is_finite(edge.measurement) || !edge.information.allFinite()) {
    throw Error("PoseGraph::add_edge: the measurement or its information is not finite");
  }
  edges_.push_back(edge);
  stats_.edges = edges_.size();
}

double PoseGraph::chi2() const {
  double sum = 0.0;
  for (const PoseGraphEdge& edge : edges_) {
    const Linearized l = linearize(poses_[edge.from], poses_[edge.to], edge.measurement);
    sum += l.e.dot(edge.information * l.e);
  }
  return sum;
}

void PoseGraph::optimize() {
  ++stats_.optimizations;
  const std::size_t n = poses_.size();
  if (n < 2 || edges_.empty()) {
    stats_.last_chi2 = chi2();
    return;
  }
  const double c2 = config_.robust_scale * config_.robust_scale;
  std::vector<Eigen::Triplet<double>> triplets;
  Eigen::SparseMatrix<double> H(static_cast<Eigen::Index>(3 * n), static_cast<Eigen::Index>(3 * n));
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver;
  bool analyzed = false;
  for (std::size_t iter = 0; iter < config_.max_iterations; ++iter) {
    ++stats_.iterations;
    triplets.clear();
    triplets.reserve(edges_.size() * 36 + 3);
    Eigen::VectorXd g = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(3 * n));
    for (const PoseGraphEdge& edge : edges_) {
      const Linearized l = linearize(poses_[edge.from], poses_[edge.to], edge.measurement);
      double w = 1.0;
      if (edge.robust) w = 1.0 / (1.0 + l.e.dot(edge.information * l.e) / c2);
      const Eigen::Matrix3d Om = w * edge.information;
      const Eigen::Matrix3d AtO = l.A.transpose() * Om, BtO = l.B.transpose() * Om;
      const std::array<std::pair<std::size_t, Eigen::Matrix3d>, 4> blocks{
          {{0, AtO * l.A}, {1, AtO * l.B}, {2, BtO * l.A}, {3, BtO * l.B}}};
      const std::size_t ia = 3 * edge.from, ib = 3 * edge.to;
      for (const auto& [which, block] : blocks) {
        const std::size_t r = which < 2 ? ia : ib, c = which % 2 == 0 ? ia : ib;
        for (int u = 0; u < 3; ++u)
          for (int v = 0; v < 3; ++v)
            triplets.emplace_back(static_cast<int>(r) + u, static_cast<int>(c) + v, block(u, v));
      }
      g.segment<3>(static_cast<Eigen::Index>(ia)) += AtO * l.e;
      g.segment<3>(static_cast<Eigen::Index>(ib)) += BtO * l.e;
    }
    // Node 0 fixed: a stiff prior on its increment.
    for (int u = 0; u < 3; ++u) triplets.emplace_back(u, u, 1e12);
    H.setFromTriplets(triplets.begin(), triplets.end());
    if (!analyzed) {
      solver.analyzePattern(H);
      analyzed = true;
    }
    solver.factorize(H);
    if (solver.info() != Eigen::Success) {
      throw Error("PoseGraph::optimize: the system is singular (a node without edges?)");
    }
    const Eigen::VectorXd dx = solver.solve(-g);
    double largest = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
      Pose2& p = poses_[i];
      const auto k = static_cast<Eigen::Index>(3 * i);
      p = Pose2(p.x + dx(k), p.y + dx(k + 1), p.theta + dx(k + 2));
      largest = std::max({largest, std::abs(dx(k)), std::abs(dx(k + 1)), std::abs(dx(k + 2))});
    }
    if (largest < config_.converged_step) break;
  }
  stats_.last_chi2 = chi2();
}

}  // namespace lshloc
