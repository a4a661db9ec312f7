#include <gtest/gtest.h>
#include "rvegen/pair.hpp"
using namespace rvegen;
TEST(Smoke, SphereSphere) {
  EXPECT_TRUE(intersect(Shape::sphere({0,0,0},1), Shape::sphere({1.5,0,0},1)).overlap);
}
