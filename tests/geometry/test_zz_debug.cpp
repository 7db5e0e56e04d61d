#include <gtest/gtest.h>
#include "evar/geometry/device_segmentation.hpp"
#include "synthetic_fluoro.hpp"
using namespace evar;
TEST(ZZ, Percentiles) {
  for (double photons : {3000.0, 300.0}) {
  const auto v = test::detector_view(30, 10);
  sim::FluoroOptions ro; ro.photons_per_pixel = photons;
  const auto frame = sim::render_fluoro(geometry::projection_matrix(v), v, {}, ro);
  geometry::SegmentationOptions so; so.device_width_px = test::shadow_width_px(v);
  cv::Mat R = geometry::ridge_response(frame.image, so);
  std::vector<float> vals; for (int y = 50; y < 974; ++y) for (int x = 50; x < 974; ++x) vals.push_back(R.at<float>(y,x));
  std::sort(vals.begin(), vals.end());
  std::cout << photons << ": ";
  for (double q : {0.5, 0.9, 0.99, 0.999, 0.9999}) std::cout << q << ":" << vals[size_t(q * vals.size())] << " ";
  std::cout << "\n";
  }
}
