// node.json: the settings a clinical engineer writes for the bedside box are read exactly
// or refused with the file and field named (docs/FORMATS.md).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "evar/base/input_error.hpp"
#include "node_config.hpp"
#include "support/error_message.hpp"

namespace fs = std::filesystem;
using testing::HasSubstr;

namespace {

fs::path write_config(const std::string& frames) {
  const fs::path file = fs::temp_directory_path() / ("evar_node_" + std::to_string(::getpid()) + ".json");
  std::ofstream(file) << R"({"format": "evarnode-node", "version": 1, "frames": )" << frames << "}";
  return file;
}

std::string error_of(const std::string& frames) {
  return evar::test::error_message([&] { evar::app::read_node_config(write_config(frames)); });
}

}  // namespace

TEST(NodeConfig, ThePacketSocketIsOptIn) {
  const auto plain = evar::app::read_node_config(write_config(R"({"camera": "EVAR001"})"));
  ASSERT_TRUE(plain.frames);
  EXPECT_EQ(plain.frames->camera, "EVAR001");
  EXPECT_FALSE(plain.frames->packet_socket);
  const auto asked = evar::app::read_node_config(write_config(R"({"camera": "", "packet_socket": true})"));
  EXPECT_TRUE(asked.frames->packet_socket);
  fs::remove(write_config("{}"));
}

TEST(NodeConfig, TheSourceFrameRateIsAskedForOnlyWhenGiven) {
  const auto given = evar::app::read_node_config(write_config(R"({"camera": "", "fps": 30})"));
  ASSERT_TRUE(given.frames && given.frames->fps);
  EXPECT_EQ(*given.frames->fps, 30.0);
  EXPECT_FALSE(given.fps);  // the video file's rate follows it (run_command.cpp)
  const auto free_running = evar::app::read_node_config(write_config(R"({"camera": ""})"));
  EXPECT_FALSE(free_running.frames->fps);
  EXPECT_THAT(error_of(R"({"fps": 0})"), HasSubstr("frames.fps"));
  fs::remove(write_config("{}"));
}

TEST(NodeConfig, BadFrameSettingsAreNamed) {
  EXPECT_THAT(error_of(R"({"packet_socket": "yes"})"), HasSubstr(".json: frames.packet_socket: expected true or false"));
  EXPECT_THAT(error_of(R"({"packet_sockets": true})"), HasSubstr("frames.packet_sockets: unknown setting"));
  EXPECT_THAT(error_of(R"({"pixel_format": "mono10"})"), HasSubstr("frames.pixel_format: expected mono8, mono12 or mono16"));
  EXPECT_THAT(error_of(R"({"width": 8})"), HasSubstr("frames.width"));
  EXPECT_THAT(error_of(R"({"width": 16384, "height": 8192})"), HasSubstr("frames: 16384 x 8192 pixels; at most 67108864 in all"));
  fs::remove(write_config("{}"));
}

TEST(NodeConfig, TheBedsideStartingConfigIsValid) {
  // scripts/install-bedside.sh installs it as /etc/evarnode/node.json.
  const auto c = evar::app::read_node_config(fs::path(EVAR_SOURCE_DIR) / "scripts/bedside/node.json");
  ASSERT_TRUE(c.frames && c.carm && c.scene && c.detector);
  EXPECT_FALSE(c.frames->packet_socket);
  EXPECT_EQ(*c.carm, "serial:/dev/evarnode-carm,baud=115200");  // the udev rule's stable name
  EXPECT_EQ(*c.scene, "/var/lib/evarnode/case/scene.json");      // inside the service's StateDirectory
  EXPECT_EQ(c.max_view_gap_s, 120.0);
}

TEST(NodeConfig, TheViewGapIsReadInSecondsAndBoundedWithItsField) {
  const fs::path file = fs::temp_directory_path() / ("evar_node_gap_" + std::to_string(::getpid()) + ".json");
  const auto with_gap = [&](const std::string& gap) {
    std::ofstream(file) << R"({"format": "evarnode-node", "version": 1, "max_view_gap_s": )" << gap << "}";
    return file;
  };
  EXPECT_EQ(evar::app::read_node_config(with_gap("30")).max_view_gap_s, 30.0);
  const std::string zero = evar::test::error_message([&] { evar::app::read_node_config(with_gap("0")); });
  EXPECT_THAT(zero, HasSubstr("max_view_gap_s"));
  EXPECT_THAT(evar::test::error_message([&] { evar::app::read_node_config(with_gap("\"2 min\"")); }),
              HasSubstr("max_view_gap_s"));
  fs::remove(file);
}

// "pelvis": the node looks for the pelvis in the bones unless told not to; anything but a
// boolean is refused with the field and what it means.
TEST(NodeConfig, ThePelvisIsLookedForUnlessTurnedOff) {
  const fs::path file = fs::temp_directory_path() / ("evar_node_pelvis_" + std::to_string(::getpid()) + ".json");
  const auto with = [&](const std::string& extra) {
    std::ofstream(file) << R"({"format": "evarnode-node", "version": 1)" << extra << "}";
    return file;
  };
  EXPECT_TRUE(evar::app::read_node_config(with("")).pelvis);
  EXPECT_TRUE(evar::app::read_node_config(with(R"(, "pelvis": true)")).pelvis);
  EXPECT_FALSE(evar::app::read_node_config(with(R"(, "pelvis": false)")).pelvis);
  const std::string error = evar::test::error_message([&] { evar::app::read_node_config(with(R"(, "pelvis": "off")")); });
  EXPECT_THAT(error, HasSubstr(".json: pelvis: expected true"));
  EXPECT_THAT(error, HasSubstr("or false"));
  fs::remove(file);
}

TEST(NodeConfig, ADetectorOfMorePixelsThanAnyImageReadIsRefused) {
  const fs::path file = fs::temp_directory_path() / ("evar_node_detector_" + std::to_string(::getpid()) + ".json");
  const auto with = [&](int cols, int rows) {
    std::ofstream(file) << R"({"format": "evarnode-node", "version": 1, "detector": {"cols": )" << cols
                        << R"(, "rows": )" << rows << R"(, "row_spacing_mm": 0.2, "col_spacing_mm": 0.2}})";
    return file;
  };
  // Each side within 16384, but 16384 x 16384 is 512 MiB a frame at 16 bits.
  EXPECT_THAT(evar::test::error_message([&] { evar::app::read_node_config(with(16384, 16384)); }),
              HasSubstr("detector: 16384 x 16384 pixels; at most 67108864 in all"));
  const auto wide = evar::app::read_node_config(with(16384, 4096));
  ASSERT_TRUE(wide.detector);
  EXPECT_EQ(wide.detector->cols, 16384);
  fs::remove(file);
}

// The video mapping (issue 31) inline, or as the file `calibrate-video` writes, beside node.json.
TEST(NodeConfig, TheVideoMappingIsGivenInlineOrAsAFileAndRefusedByField) {
  const fs::path dir = fs::temp_directory_path() / ("evar_node_mapping_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const std::string mapping = R"({"format": "evarnode-video-mapping", "version": 1, "video_size_px": [1280, 1024],
      "image_rect_px": [128, 0, 1024, 1024], "mirror": true, "rotation_deg": 90, "field_shape": "circle",
      "text_regions_px": [[0, 0, 120, 40]]})";
  const auto config = [&](const std::string& value) {
    std::ofstream(dir / "node.json") << R"({"format": "evarnode-node", "version": 1, "video_mapping": )" << value << "}";
    return dir / "node.json";
  };
  const auto inline_given = evar::app::read_node_config(config(mapping));
  ASSERT_TRUE(inline_given.video_mapping);
  EXPECT_EQ(inline_given.video_mapping->video_cols, 1280);
  EXPECT_EQ(inline_given.video_mapping->image_rect.x, 128);
  EXPECT_TRUE(inline_given.video_mapping->mirror);
  EXPECT_EQ(inline_given.video_mapping->rotation_deg, 90);
  EXPECT_EQ(inline_given.video_mapping->field_shape, evar::geometry::FieldShape::Circle);
  ASSERT_EQ(inline_given.video_mapping->text_regions.size(), 1u);

  std::ofstream(dir / "mapping.json") << mapping;
  const auto from_file = evar::app::read_node_config(config(R"("mapping.json")"));
  ASSERT_TRUE(from_file.video_mapping);
  EXPECT_EQ(from_file.video_mapping->rotation_deg, 90);
  EXPECT_EQ(from_file.video_mapping->image_rect.width, 1024);

  const auto error = [&](const std::string& value) {
    return evar::test::error_message([&] { evar::app::read_node_config(config(value)); });
  };
  EXPECT_THAT(error("1"), HasSubstr("node.json: video_mapping: expected the mapping's object or the name of its file"));
  EXPECT_THAT(error(R"({"format": "evarnode-video-mapping", "version": 1, "video_size_px": [640, 480],
                       "image_rect_px": [0, 0, 640, 480], "rotation": 90})"),
              HasSubstr("node.json: video_mapping.rotation: not a field of a video mapping"));
  EXPECT_THAT(error(R"("missing.json")"), HasSubstr("node.json: video_mapping: the mapping it names:"));
  EXPECT_THAT(error(R"("missing.json")"), HasSubstr("missing.json"));
  fs::remove_all(dir);
}

TEST(NodeConfig, ZoomModesAreReadAgainstThePhysicalDetectorAndAFixedModeMustBeListed) {
  const fs::path file = fs::temp_directory_path() / ("evar_node_zoom_" + std::to_string(::getpid()) + ".json");
  const std::string detector = R"("detector": {"cols": 1024, "rows": 1024, "row_spacing_mm": 0.390625, "col_spacing_mm": 0.390625})";
  const std::string modes = R"("zoom_modes": [
      {"mode": 1, "name": "40 cm", "field_of_view_dimensions_mm": [400, 400], "image_size_px": [1024, 1024],
       "imager_pixel_spacing_mm": [0.390625, 0.390625]},
      {"mode": 3, "name": "20 cm", "field_of_view_shape": "ROUND", "field_of_view_dimensions_mm": [200],
       "image_size_px": [512, 512], "imager_pixel_spacing_mm": [0.390625, 0.390625], "field_of_view_origin_px": [100, 412]}])";
  const auto with = [&](const std::string& fields) {
    std::ofstream(file) << R"({"format": "evarnode-node", "version": 1, )" << fields << "}";
    return file;
  };
  const auto c = evar::app::read_node_config(with(detector + ", " + modes + R"(, "zoom_mode": 3)"));
  ASSERT_EQ(c.zoom_modes.size(), 2u);
  EXPECT_EQ(c.zoom_modes[1].name, "20 cm");
  EXPECT_EQ(c.zoom_modes[1].shape, evar::geometry::FieldShape::Circle);
  EXPECT_EQ(c.zoom_modes[1].cols, 512);
  ASSERT_TRUE(c.zoom_modes[1].origin_rows_cols);
  EXPECT_EQ(c.zoom_modes[1].origin_rows_cols->y(), 412.0);
  EXPECT_EQ(c.zoom_mode, 3);
  const auto error = [&](const std::string& fields) {
    return evar::test::error_message([&] { evar::app::read_node_config(with(fields)); });
  };
  EXPECT_THAT(error(modes), HasSubstr(".json: zoom_modes: needs \"detector\""));
  EXPECT_THAT(error(detector + R"(, "zoom_mode": 1)"), HasSubstr(".json: zoom_mode: needs \"zoom_modes\""));
  EXPECT_THAT(error(detector + ", " + modes + R"(, "zoom_mode": 2)"),
              HasSubstr(".json: zoom_mode: must be the number of one of zoom_modes, found 2"));
  // The field placed past the detector's right edge.
  std::string off = modes;
  off.replace(off.find("[100, 412]"), 10, "[100, 600]");
  EXPECT_THAT(error(detector + ", " + off), HasSubstr("zoom_modes[1].field_of_view_origin_px: the field placed there"));
  fs::remove(file);
}
