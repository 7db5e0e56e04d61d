#include "evar/overlay/mesh_preview.hpp"

#include <gtest/gtest.h>

TEST(MeshPreview, Placeholder) {}
