#include "lshloc/geometry/pose2.hpp"

#include <cassert>

namespace lshloc {

void Pose2::transform(std::span<const Point2> in, std::span<Point2> out) const {
  assert(in.size() == out.size());
  const double c = std::cos(theta), s = std::sin(theta);
  for (std::size_t i = 0; i < in.size(); ++i) {
    const double px = in[i].x(), py = in[i].y();
    out[i] = Point2(x + c * px - s * py, y + s * px + c * py);
  }
}

}  // namespace lshloc
