#include "rvegen/model/inclusion_set.hpp"

#include <cmath>
#include <string>

namespace rvegen {

namespace {
// Box sizes the arithmetic serves (the messages say so).
constexpr double kMinBoxSize = 1e-12, kMaxBoxSize = 1e12;
}  // namespace

void check_box(const Box& b, const std::string& path) {
  for (int k = 0; k < 3; ++k) {
    const std::string sk = path + ".size[" + std::to_string(k) + "]";
    if (!std::isfinite(b.size[k]) || !(b.size[k] > 0.0)) {
      throw InputError(sk + ": must be positive and finite");
    }
    if (b.size[k] < kMinBoxSize || b.size[k] > kMaxBoxSize)
      throw InputError(sk + ": must be in [1e-12, 1e12]");
    const std::string ok = path + ".origin[" + std::to_string(k) + "]";
    if (!std::isfinite(b.origin[k])) throw InputError(ok + ": must be finite");
    if (std::abs(b.origin[k]) > 1000.0 * b.size[k]) {
      throw InputError(ok +
                       ": must be within 1000 box sizes of 0 (coordinates would lose the "
                       "precision the overlap tests need)");
    }
  }
  if (b.size.maxCoeff() > 1e6 * b.size.minCoeff()) {
    throw InputError(path + ".size: the largest size may be at most 1e6 times the smallest");
  }
}

}  // namespace rvegen
