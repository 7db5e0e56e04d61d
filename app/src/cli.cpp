#include "evar/app/cli.hpp"

#include <CLI/CLI.hpp>
#include <exception>

#include "commands.hpp"
#include "evar/geometry/image_header.hpp"
#include "evar/base/input_error.hpp"
#include "evar/node/logging.hpp"
#include "evar/session/session_replay.hpp"

namespace evar::app {

int run_cli(const std::vector<std::string>& args) {
  CLI::App app{
      "evarnode: adapts preoperative CT vessel meshes (aorta, iliacs) to a guidewire seen in\n"
      "intraoperative fluoroscopy during EVAR, by skeleton-based as-rigid-as-possible\n"
      "deformation (Toth et al.). Coordinates are patient LPS millimetres throughout.\n",
      "evarnode"};
  app.require_subcommand(1);
  app.fallthrough();  // --log-level may follow the subcommand
  std::string log_level = "info";
  app.add_option("--log-level", log_level, "error, warn, info or debug")
      ->check(CLI::IsMember({"error", "warn", "info", "debug"}))
      ->capture_default_str();

  DeformCommand deform;
  auto* d = app.add_subcommand("deform",
                               "Deform a scene's vessel meshes so they contain the device.\n"
                               "Writes OUT/<mesh file> per vessel (same format, vertex order and count; faces\n"
                               "of erased aortic vertices removed), OUT/landmarks.mrk.json, OUT/report.json\n"
                               "and OUT/preview.png. Warns when the deformed vessels leave part of the device\n"
                               "outside their walls (report.json: device_outside_length_mm, device_outside_max_depth_mm).");
  d->add_option("--scene", deform.scene, "scene.json (format evarnode-scene, version 1)")->required();
  d->add_option("--device", deform.device, "device as a 3D Slicer Curve markup (.mrk.json), tip first")->required();
  d->add_option("--out", deform.out, "output directory (created if missing)")->required();
  d->add_flag("!--no-skeleton", deform.skeleton, "plain surface ARAP, without the skeleton (for comparison)");
  d->add_flag("!--no-preview", deform.preview, "do not write preview.png");
  d->add_flag("--strict", deform.strict,
              "exit with code 4 (after writing every output) when the warning above is given: for scripts\n"
              "that must not pass such a result on");
  d->add_option("--solver", deform.solver, "sparse Cholesky: default, eigen or cholmod")
      ->check(CLI::IsMember({"default", "eigen", "cholmod"}))
      ->capture_default_str();
  d->add_option("--tolerance-mm", deform.tolerance_mm, "stop when the largest vertex update is below this")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  d->add_option("--max-iterations", deform.max_iterations, "cap on ARAP iterations per solve")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  d->add_option("--containment-rounds", deform.containment_rounds,
                "re-select handles on the deformed surface up to this many solves per vessel (1 = single pass)")
      ->check(CLI::Range(1, 20))
      ->capture_default_str();

  d->add_option("--tether-mm", deform.tether_mm,
                "length scale of the weak tether to the registered pose; 0 = off (handles only, as in the paper)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  d->add_option("--proxy-edge-mm", deform.proxy_edge_mm,
                "a vessel mesh whose median edge is under 3/4 of this is solved on a coarser proxy with edges\n"
                "of about this length, and its own vertices follow (finely meshed CT in the time and with the\n"
                "result of the paper's resolution); 0 = every mesh solved as it is")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  d->add_option("--pelvis-shift-mm", deform.pelvis_shift_mm,
                "X Y Z: how far the pelvis lies from where the registration put it (scene LPS mm), as a bony\n"
                "2D/3D registration measures it: the models are moved before they are bent, nothing at the renal\n"
                "level, all of it from the aortic bifurcation down, a smooth ramp between (docs/DEFORMATION.md)")
      ->expected(3);
  d->add_flag("!--no-coarse-rotations", deform.coarse_rotations,
              "plain local/global on the iliacs too, without turning their rotations by the coarse space "
              "(for comparison; docs/DEFORMATION.md)");
  d->add_flag("!--nearest-pairing", deform.ordered_pairing,
              "cast each iliac section's ray to its nearest device point (the paper's rays) instead of pairing\n"
              "sections and device points in the order both run in (for comparison; docs/DEFORMATION.md)");

  SceneCommand scene_cmd;
  auto* sc = app.add_subcommand(
      "scene",
      "Make a scene directory (scene.json, one mesh and centerline per vessel, landmarks) from one\n"
      "aorto-iliac surface as a segmentation tool exports it, with or without its centerlines: the\n"
      "surface is cut into the aorta and both iliacs, the centerlines (computed from the surface when\n"
      "none are given) trimmed and run proximal to distal, the iliacs told right from left, clicked\n"
      "ostia put on the wall. Writes OUT/scene_report.json and OUT/scene.png, and loads the result\n"
      "as `deform` will. Examples (VMTK's data, a surface in image axes whose y runs to the head):\n"
      "  evarnode scene --surface aorta-surface.vtp --centerlines aorta-centerline.vtp --axes RSP --out S\n"
      "  evarnode scene --surface aorta-surface.stl --axes RSP --out S");
  sc->add_option("--surface", scene_cmd.surface,
                 "the surface (STL, PLY, OBJ, VTK or VTP; closed or open; one connected piece)")
      ->required();
  sc->add_option("--centerlines", scene_cmd.centerlines,
                 "its centerlines: VMTK's .vtp (vmtkcenterlines paths, or vmtkbranchextractor pieces) or 3D Slicer\n"
                 "markups curves (.mrk.json), from the aortic inlet to both iliac outlets. Default: computed from\n"
                 "the surface (its mean-curvature-flow skeleton, CGAL; seconds on a large surface)");
  sc->add_option("--ostia", scene_cmd.ostia, "ostia clicked in 3D Slicer (fiducials, .mrk.json): the landmarks");
  sc->add_option("--axes", scene_cmd.axes,
                 "the patient direction each axis of the surface file points to (x, y, z), e.g. RSP for a surface\n"
                 "in image axes whose y runs to the head; default: the file's SPACE tag, else LPS. A file whose\n"
                 "aorta does not run to the head is refused, never rotated silently");
  sc->add_option("--out", scene_cmd.out, "output directory (created if missing)")->required();
  sc->add_option("--device-thickness-mm", scene_cmd.device_thickness_mm, "the device's diameter written into scene.json")
      ->check(CLI::Range(0.0, 10.0))
      ->capture_default_str();
  sc->add_flag("!--no-picture", scene_cmd.picture, "do not write scene.png");

  ProxiesCommand proxies;
  auto* px = app.add_subcommand(
      "proxies",
      "Make the proxies of a scene's finely meshed vessels and keep them beside their meshes, named in\n"
      "scene.json (docs/FORMATS.md, \"Proxy files\"), so deform, run and record read them in milliseconds\n"
      "instead of remeshing at every load. `evarnode scene` does this for the scenes it makes; this is for\n"
      "scenes put together otherwise. Rewrites scene.json (its other fields kept); run it again after\n"
      "editing a mesh. Example:\n"
      "  evarnode proxies --scene S/scene.json");
  px->add_option("--scene", proxies.scene, "scene.json (format evarnode-scene, version 1)")->required();
  px->add_option("--proxy-edge-mm", proxies.proxy_edge_mm,
                 "the proxies' edge; deform reads a proxy file only when given the same --proxy-edge-mm")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();

  ArapCommand arap;
  auto* a = app.add_subcommand("arap",
                               "Plain surface ARAP for explicit constraints (no skeleton), to compare the\n"
                               "solver with other ARAP implementations on identical problems.\n"
                               "constraints JSON: {\"fixed\": [vertex...], \"handles\": [{\"vertex\": i, \"target\": [x,y,z]}]}");
  a->add_option("--mesh", arap.mesh, "input mesh (.stl, .ply, .obj, .vtk)")->required();
  a->add_option("--constraints", arap.constraints,
                "constraints JSON; targets in the mesh file's coordinates (RAS if its header says SPACE=RAS)")
      ->required();
  a->add_option("--out", arap.out,
                "output mesh (format from its extension, in the input's coordinate system)")->required();
  auto* it = a->add_option("--iterations", arap.iterations, "run exactly N iterations after the initial guess")
                 ->check(CLI::NonNegativeNumber);
  auto* tol = a->add_option("--tolerance-mm", arap.tolerance_mm, "stop when the largest update is below T (default 0.01)")
                  ->check(CLI::PositiveNumber);
  it->excludes(tol);
  a->add_option("--report", arap.report, "write a JSON report (timings, iterations, energy)");
  a->add_option("--solver", arap.solver, "sparse Cholesky: default, eigen or cholmod")
      ->check(CLI::IsMember({"default", "eigen", "cholmod"}))
      ->capture_default_str();
  a->add_flag("!--no-anderson", arap.anderson, "plain local/global iterations (no Anderson acceleration)");

  // Mesh format and resolution of the synthetic scenes (example, sim patient).
  const auto add_mesh_options = [](CLI::App* c, SyntheticSceneCommand& cmd) {
    c->add_option("--format", cmd.format, "mesh format: stl, ply, obj, vtk or vtp")
        ->check(CLI::IsMember({"stl", "ply", "obj", "vtk", "vtp"}))
        ->capture_default_str();
    c->add_option("--aorta-vertices", cmd.aorta_vertices, "approximate aortic mesh size")
        ->check(CLI::Range(500, 2000000))
        ->capture_default_str();
    c->add_option("--iliac-vertices", cmd.iliac_vertices, "approximate size of each iliac mesh")
        ->check(CLI::Range(300, 2000000))
        ->capture_default_str();
  };
  // How hard a synthetic patient is and which mechanics makes its truth (sim patient, sim session).
  const auto add_truth_options = [](CLI::App* c, std::string& difficulty, std::string& physics) {
    c->add_option("--difficulty", difficulty,
                  "mild: moderately tortuous iliacs, 30-60 mm bending-length wires, exact registration;\n"
                  "paper: the seed paper's initial error (tortuous iliacs, Amplatz Super Stiff to Lunderquist\n"
                  "wires, a pelvis shifted against the renal level, and in sessions a registration residual of up\n"
                  "to 5 deg about each axis and 1 mm along each, about the renal level)")
        ->check(CLI::IsMember({"mild", "paper"}))
        ->capture_default_str();
    c->add_option("--physics", physics,
                  "the ground truth's mechanics: beam (centerline beams pushed by contact) or conforming\n"
                  "(the iliac threaded on the wire, folding and sliding; docs/SYNTHETIC_PATIENTS.md)")
        ->check(CLI::IsMember({"beam", "conforming"}))
        ->capture_default_str();
  };
  SyntheticSceneCommand example;
  auto* e = app.add_subcommand("example",
                               "Write the bundled synthetic aorto-iliac example scene (meshes, centerlines,\n"
                               "landmarks, a guidewire that leaves the undeformed right iliac) to a directory.");
  e->add_option("--out", example.out, "output directory")->required();
  e->add_option("--seed", example.seed, "anatomy variation seed")->capture_default_str();
  add_mesh_options(e, example);

  ProjectCommand project;
  auto* pr = app.add_subcommand("project",
                                "Print the pixel coordinates of points in a C-arm view (to check the projection\n"
                                "conventions by hand: docs/CARM_GEOMETRY.md). Points in C-arm coordinates (LPS mm,\n"
                                "isocenter at the origin), or in CT LPS with --registration.");
  pr->add_option("--geometry", project.geometry, "view geometry JSON (docs/FORMATS.md) or a DICOM XA / Enhanced XA file")
      ->required();
  pr->add_option("--registration", project.registration, "CT to C-arm registration JSON {\"matrix\": 4x4}");
  pr->add_option("--points", project.points, "points: any 3D Slicer markups file (.mrk.json), labels kept")->required();
  pr->add_option("--out", project.out, "also write the result as JSON");

  CalibrateVideoCommand calibrate;
  auto* cv = app.add_subcommand(
      "calibrate-video",
      "Find where the fluoroscopy image lies in frames grabbed from a C-arm's video output (the\n"
      "monitor's picture): the image area, its shape (rectangle or an image intensifier's circle)\n"
      "and the burned-in text around it. Writes the video mapping (docs/FORMATS.md, \"Video\n"
      "mapping\") and a picture to check it by. Grab a few frames while fluoroscopy is shown.");
  cv->add_option("--frames", calibrate.frames, "grabbed frames (PNG, TIFF, ...; 8 or 16 bit; all of one size)")
      ->required()
      ->check(CLI::ExistingFile);
  cv->add_option("--out", calibrate.out, "the mapping file to write (JSON)")->required();
  cv->add_option("--picture", calibrate.picture, "also draw what was found (PNG)");
  cv->add_option("--node", calibrate.node,
                 "also point this node.json's \"video_mapping\" at the mapping file (other fields kept;\n"
                 "left alone when the shape does not fit the detector)")
      ->check(CLI::ExistingFile);
  cv->add_option("--rotation-deg", calibrate.rotation_deg,
                 "the display's turn, clockwise as shown (0, 90, 180, 270): from the C-arm's display settings")
      ->check(CLI::IsMember({0, 90, 180, 270}))
      ->capture_default_str();
  cv->add_flag("--mirror", calibrate.mirror, "the display mirrors the image left to right (after the turn)");
  cv->add_option("--detector-px", calibrate.detector_px,
                 "the detector's cols and rows: check the image area's shape against it (default: node.json's\n"
                 "detector with --node); exit 1 when it does not fit")
      ->expected(2);

  const auto add_segment_params = [](CLI::App* c, SegmentParams& p) {
    c->add_option("--device-diameter-mm", p.diameter_mm, "device diameter, for its shadow width with the geometry")
        ->check(CLI::Range(0.1, 10.0))
        ->capture_default_str();
    c->add_option("--width-px", p.width_px, "shadow width in pixels (instead of diameter and geometry)")
        ->check(CLI::Range(0.5, 100.0));
    c->add_option("--min-contrast", p.min_contrast,
                  "least device contrast, -log units of raw detector data; 0 for processed video")
        ->check(CLI::Range(0.0, 10.0))
        ->capture_default_str();
  };
  SegmentCommand segment;
  auto* sg = app.add_subcommand("segment",
                                "Find the guidewire or catheter in one fluoroscopy frame and write it as an\n"
                                "ordered sub-pixel polyline, tip first, with a confidence (JSON). Exit code 3\n"
                                "when the frame holds no device (the JSON then says why).");
  sg->add_option("--image", segment.image, "frame: PNG or TIFF (8 or 16 bit, grey) or DICOM XA / Enhanced XA")->required();
  sg->add_option("--geometry", segment.geometry, "view geometry JSON or DICOM (sets the expected device width)");
  sg->add_option("--out", segment.out, "result JSON (format evarnode-device-2d)")->required();
  sg->add_option("--overlay", segment.overlay, "also write the frame with the device drawn on it (PNG)");
  sg->add_option("--seed", segment.params.seed, "u v: a click on or near the tip (pixels)")->expected(2);
  add_segment_params(sg, segment.params);

  ReconstructCommand reconstruct;
  auto* rc = app.add_subcommand("reconstruct",
                                "The device in 3D from two frames at different C-arm angulations: segments\n"
                                "both, matches them along epipolar lines, triangulates. Writes a 3D Slicer Curve\n"
                                "markup (tip first) that `evarnode deform --device` reads.");
  rc->add_option("--image", reconstruct.images, "a frame (give twice): PNG/TIFF with --geometry, or DICOM XA")
      ->required()
      ->expected(1)
      ->take_all();
  rc->add_option("--geometry", reconstruct.geometries, "view geometry of each --image, in the same order (or none for DICOM)")
      ->expected(1)
      ->take_all();
  rc->add_option("--registration", reconstruct.registration,
                 "CT to C-arm registration JSON: the curve is written in CT LPS (else C-arm coordinates)");
  rc->add_option("--out", reconstruct.out, "device curve (.mrk.json)")->required();
  rc->add_option("--report", reconstruct.report, "JSON report: per-view segmentation, residuals, timings");
  rc->add_option("--overlay-prefix", reconstruct.overlay_prefix, "write PREFIX1.png and PREFIX2.png with the curves drawn");
  rc->add_option("--min-separation-deg", reconstruct.min_separation_deg, "refuse views closer than this")
      ->check(CLI::Range(1.0, 90.0))
      ->capture_default_str();
  add_segment_params(rc, reconstruct.params);

  auto* sim = app.add_subcommand("sim", "Synthetic material for development and evaluation (docs/SYNTHETIC_PATIENTS.md).");
  sim->require_subcommand(1);
  SyntheticSceneCommand sim_patient;
  auto* sp = sim->add_subcommand(
      "patient",
      "Write a synthetic aorto-iliac patient drawn from adult ranges by a seed: the preoperative\n"
      "scene (OUT/scene.json, meshes, centerlines, landmarks.mrk.json), the inserted device\n"
      "(OUT/device.mrk.json), the ground truth of how the device distorts the vessels (OUT/truth/,\n"
      "a scene of the same layout with the same vertex order, made by a model other than the\n"
      "product's ARAP) and OUT/patient.json (parameters and a summary). Then, e.g.:\n"
      "  evarnode deform --scene OUT/scene.json --device OUT/device.mrk.json --out RESULT\n"
      "and compare RESULT with OUT/truth/.");
  sp->add_option("--seed", sim_patient.seed, "patient seed (the same seed gives the same patient)")->capture_default_str();
  sp->add_option("--out", sim_patient.out, "output directory (created if missing)")->required();
  add_mesh_options(sp, sim_patient);
  add_truth_options(sp, sim_patient.difficulty, sim_patient.physics);

  SimSessionCommand sim_session;
  auto* ss = sim->add_subcommand(
      "session",
      "Write a whole simulated intervention as a recorded session (docs/SESSION_FORMAT.md): a\n"
      "synthetic patient (as `sim patient`, under OUT/patient/), fluoroscopy of the inserted device in\n"
      "AP, LAO 35 and the carrier's bifurcation view with the C-arm moving between them, DSA-like\n"
      "contrast frames of the iliac bifurcation, and the ground truth (true 2D ostia per frame).\n"
      "Play it with `evarnode replay OUT`.");
  ss->add_option("--seed", sim_session.seed, "patient and noise seed")->capture_default_str();
  ss->add_option("--out", sim_session.out, "session directory (created if missing)")->required();
  ss->add_option("--detector-px", sim_session.detector_px, "square detector size in pixels (0.3 mm pixels at 1024)")
      ->check(CLI::Range(64, 4096))
      ->capture_default_str();
  ss->add_option("--fluoro-seconds", sim_session.fluoro_seconds, "length of each fluoroscopy run")
      ->check(CLI::Range(0.1, 600.0))
      ->capture_default_str();
  ss->add_option("--fps", sim_session.fluoro_fps, "pulsed fluoroscopy rate")->check(CLI::Range(1.0, 60.0))->capture_default_str();
  add_truth_options(ss, sim_session.difficulty, sim_session.physics);
  ss->add_option("--video-out", sim_session.video_out,
                 "a video mapping (docs/FORMATS.md, \"Video mapping\"): the frames are the C-arm monitor's picture "
                 "through it (scaled, bordered, turned, mirrored, text burned in), as a box on the video output grabs them");
  ss->add_flag("--zoom-change", sim_session.zoom_change,
               "the C-arm has two zoom modes (1: the whole detector, 2: its central two thirds in as many pixels), "
               "listed in session.json; the last fluoroscopy run switches to mode 2 halfway (docs/FORMATS.md, \"Zoom modes\")");
  ss->add_flag("!--no-progress", sim_session.progress, "no progress bar");

  ReplayCommand replay;
  auto* rp = app.add_subcommand(
      "replay",
      "Play a recorded session (docs/SESSION_FORMAT.md) through the same frame-source and C-arm\n"
      "geometry-source interfaces the hardware uses, in real time (recorded timestamps) or as fast\n"
      "as possible, and report what arrived: frames, drops, C-arm states, views, moving periods.");
  rp->add_option("session", replay.session, "session directory")->required();
  auto* speed = rp->add_option("--speed", replay.speed, "playback speed (1 = real time)")
                    ->check(CLI::Range(session::kMinReplaySpeed, session::kMaxReplaySpeed))
                    ->capture_default_str();
  rp->add_flag("--fast", replay.fast, "as fast as possible (no pacing)")->excludes(speed);
  rp->add_option("--loop", replay.loops, "times through the session; 0 = until interrupted")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  rp->add_flag("--preload", replay.preload,
               "decode every frame before playing and keep them in memory (frames x width x height x 2 bytes), so "
               "frames leave on time and the decoding takes no CPU from a node measured beside it");
  rp->add_option("--report", replay.report, "write a JSON report");
  rp->add_flag("!--no-progress", replay.progress, "no progress bar");
  rp->add_option("--serve-gige", replay.serve_gige,
                 "also show the frames as a GigE Vision camera with this serial number (id\n"
                 "Aravis-Fake-SERIAL), which evarnode's GigE source or any GigE Vision viewer can open");
  rp->add_option("--gige-interface", replay.gige_interface, "network interface of that camera")
      ->capture_default_str();
  rp->add_option("--serve-carm", replay.serve_carm,
                 "also send the C-arm states over a pseudo-terminal in the C-arm link protocol\n"
                 "(docs/CARM_LINK_PROTOCOL.md); PATH becomes a link to its serial device");

  ExportCommand export_cmd;
  auto* ex = app.add_subcommand(
      "export",
      "Write a recorded session's frames as a PLUS toolkit sequence metafile (.seq.mha), with\n"
      "each frame's timestamp (whole milliseconds, strictly increasing) and the C-arm angulation,\n"
      "SID and SOD in force as frame fields (docs/SESSION_FORMAT.md). PLUS reads it; 3D Slicer\n"
      "loads it as an image sequence with the SlicerIGSIO extension installed (File > Add Data;\n"
      "core Slicer reads a .seq.mha only as a transform sequence). 16-bit grey levels as\n"
      "recorded; about 2 MB per 1024 x 1024 frame. --out must be outside the session.");
  ex->add_option("session", export_cmd.session, "session directory")->required();
  ex->add_option("--out", export_cmd.out, "the sequence file to write (name it *.seq.mha), outside the session")->required();
  ex->add_flag("!--no-progress", export_cmd.progress, "no progress bar");

  DevicesCommand devices;
  auto* dv = app.add_subcommand(
      "devices",
      "List the acquisition hardware this machine sees: GigE Vision cameras (Aravis discovery),\n"
      "V4L2 video devices, serial ports (with their stable /dev/serial/by-id names) and USB\n"
      "devices with their bulk/interrupt IN endpoints, for choosing --camera, --v4l2 and --carm.");
  dv->add_flag("--json", devices.json, "machine-readable output on stdout");
  dv->add_option("--usb", devices.usb, "only USB devices with this VID:PID[:SERIAL] (hexadecimal, as lsusb prints)");

  RecordCommand record;
  auto* rd = app.add_subcommand(
      "record",
      "Record a live session from a frame grabber and the C-arm link into the session format\n"
      "(docs/SESSION_FORMAT.md), with live statistics; stop with Ctrl-C (or SIGTERM, SIGHUP),\n"
      "--seconds or --frames. A recording that was killed instead (its --out holds journal/)\n"
      "becomes a session with `evarnode record --recover OUT`.\n"
      "Frames are written as 16-bit PNG (8-bit grey x257, 12-bit x16); C-arm states are put on\n"
      "the frames' clock. The patient scene is copied in, so `evarnode replay` and `evarnode run`\n"
      "take the session as it is. A report of what arrived and what was lost goes beside it\n"
      "(record_report.json).\n"
      "Example: evarnode record --camera EVAR001 --carm serial:/dev/ttyUSB0 --scene plan/scene.json\n"
      "         --registration plan/registration.json --pixel-spacing 0.154 --out session-01");
  auto* cam = rd->add_option("--camera", record.frames.camera, "GigE Vision camera: id, serial number or IP address (see `evarnode devices`)");
  auto* v4l = rd->add_option("--v4l2", record.frames.v4l2, "V4L2 frame grabber instead, e.g. /dev/video0");
  cam->excludes(v4l);
  rd->add_option("--pixel-format", record.frames.pixel_format, "GigE pixel format")
      ->check(CLI::IsMember({"mono8", "mono12", "mono16"}))
      ->capture_default_str();
  rd->add_flag("--gige-packet-socket", record.frames.packet_socket,
              "let Aravis use its packet socket (less CPU per packet); only if the process holds\n"
              "CAP_NET_RAW (see docs/SECURITY.md), otherwise plain UDP")
      ->excludes(v4l);
  rd->add_option("--v4l2-format", record.frames.v4l2_format, "V4L2 format: Y16, GREY, YUYV or MJPG (default: the deepest grey offered)")
      ->needs(v4l);
  rd->add_option("--width", record.frames.width, "image width (pixels); default: the device's")->check(CLI::Range(16, 16384));
  rd->add_option("--height", record.frames.height, "image height (pixels); default: the device's")->check(CLI::Range(16, 16384));
  rd->add_option("--fps", record.frames.fps, "frame rate (Hz); default: the device's")->check(CLI::Range(0.1, 1000.0));
  // Required for a recording, refused with --recover: checked once parsing is done.
  const std::vector<CLI::Option*> recording_options{
      rd->add_option("--carm", record.carm,
                     "the C-arm link (docs/CARM_LINK_PROTOCOL.md): serial:/dev/ttyUSB0[,baud=115200][,parity=none|even|odd][,stop=1|2]\n"
                     "or usb:VID:PID[:SERIAL] (required)"),
      rd->add_option("--scene", record.scene, "the patient's scene.json (docs/FORMATS.md) (required)")->check(CLI::ExistingFile),
      rd->add_option("--registration", record.registration, "CT-to-C-arm registration ({\"matrix\": 4x4}) (required)")
          ->check(CLI::ExistingFile),
      rd->add_option("--pixel-spacing", record.pixel_spacing_mm, "detector pixel spacing (mm, at the detector) (required)")
          ->check(CLI::Range(0.001, 10.0)),
      rd->add_option("--out", record.out, "the new session directory (must not exist or be empty) (required)")};
  const std::vector<CLI::Option*> recording_extras{
      cam, v4l,
      rd->add_option("--device-thickness", record.device_thickness_mm, "device thickness (mm); default: the scene's")
          ->check(CLI::Range(0.0, 15.0)),
      rd->add_option("--video-mapping", record.video_mapping,
                     "the frames are the C-arm's video output: where the detector image lies in them\n"
                     "(`evarnode calibrate-video`; needs --detector-px); the session carries it")
          ->check(CLI::ExistingFile),
      rd->add_option("--detector-px", record.detector_px, "with --video-mapping: the detector's cols and rows")->expected(2),
      rd->add_option("--zoom-modes", record.zoom_modes,
                     "a node.json with the C-arm's \"detector\" and \"zoom_modes\" (docs/FORMATS.md, \"Zoom modes\"): the\n"
                     "session lists them and records each C-arm state's mode; its detector is node.json's (--pixel-spacing\n"
                     "must agree, --detector-px is not needed). Without it a mode the C-arm link says is not kept")
          ->check(CLI::ExistingFile),
      rd->add_option("--seconds", record.seconds, "stop after this long")->check(CLI::PositiveNumber),
      rd->add_option("--frames", record.frames_to_write, "stop after this many frames are written")->check(CLI::PositiveNumber)};
  auto* recover = rd->add_option("--recover", record.recover,
                                 "instead of recording: make the session of an unfinished recording (the --out of a\n"
                                 "recorder that was killed, which holds journal/) from its journal, with every frame\n"
                                 "whose PNG is whole and every C-arm state");
  for (auto* o : recording_options) recover->excludes(o);
  for (auto* o : recording_extras) recover->excludes(o);
  rd->callback([recover, recording_options, &record] {
    if (recover->count() > 0) return;
    for (const auto* o : recording_options)
      if (o->count() == 0) throw CLI::RequiredError(o->get_name() + " (or --recover DIR)");
    // Each side may reach 16384, but a session's frames hold at most kMaxImagePixels in all
    // (what every evarnode image reader takes): refused now rather than at the first frame.
    const auto& f = record.frames;
    if (f.width && f.height && std::int64_t{*f.width} * *f.height > geometry::kMaxImagePixels)
      throw CLI::ValidationError("--width x --height", std::to_string(*f.width) + " x " + std::to_string(*f.height) +
                                                          " pixels; a session's frames hold at most " +
                                                          std::to_string(geometry::kMaxImagePixels) + " in all");
  });

  RunCommand run;
  auto* rn = app.add_subcommand(
      "run",
      "The live node: grabs frames and the C-arm geometry (node.json: GigE or V4L2, serial or USB) or\n"
      "replays a recorded session, reconstructs the device from two views in the background, adapts\n"
      "the vessels and composites the roadmap (translucent fill, outline, labelled ostia, device,\n"
      "status) onto every frame. Outputs in --out: the video, snapshots before/after each new model,\n"
      "run_report.json (counts, latency p50/p99) and, for sessions with ground truth, eval.md; and\n"
      "OpenIGTLink (IMAGE, POLYDATA, POINT) to 3D Slicer on 127.0.0.1:18944.");
  rn->add_option("--config", run.config, "node.json (docs/FORMATS.md); optional with --replay")->check(CLI::ExistingFile);
  rn->add_option("--replay", run.replay, "a recorded session instead of live sources")->check(CLI::ExistingDirectory);
  rn->add_option("--out", run.out, "output directory (created)")->capture_default_str();
  rn->add_option("--video", run.video, "video file in --out: .avi (Motion-JPEG), .mp4 or .mkv")->capture_default_str();
  rn->add_flag("--no-video", run.no_video, "write no video");
  rn->add_option("--video-budget-mb", run.video_budget_mb,
                 "disk kept for the video: it is written in segments of an eighth of this (the current one is the "
                 "--video name, finished ones NAME-0001, -0002, ...) and the oldest are deleted past it; about 10 GB "
                 "an hour at 1024 x 1024; 0 = one file, no limit")
      ->check(CLI::Range(0.0, 1e9))
      ->capture_default_str();
  rn->add_option("--snapshot-budget-mb", run.snapshot_budget_mb,
                 "disk kept for the before/after pictures of model changes in --out/snapshots; past it the oldest "
                 "are deleted (pictures taken with the s key never are); 0 = no limit")
      ->check(CLI::Range(0.0, 1e9))
      ->capture_default_str();
  rn->add_flag("!--no-igtl", run.igtl, "no OpenIGTLink server");
  rn->add_option("--igtl-port", run.igtl_port, "OpenIGTLink port (0 = any free one)")->check(CLI::Range(0, 65535))->capture_default_str();
  rn->add_option("--igtl-bind", run.igtl_bind, "address the server listens on (0.0.0.0 = every interface)")->capture_default_str();
  rn->add_flag("--display", run.display, "show the frames in a window (keys: m mode, s snapshot, f fullscreen, q quit)");
  rn->add_flag("--fullscreen", run.fullscreen, "the window fullscreen (the bedside monitor)");
  rn->add_flag("!--no-pelvis", run.pelvis,
               "leave the models where the registration put them; by default, where the scene has the pelvis's\n"
               "bones, the pelvis is found in the fluoroscopy (from the second view on) and the models move with it\n"
               "before they are bent (node.json \"pelvis\": false does the same; docs/DEFORMATION.md, \"The pelvis\")");
  rn->add_option("--mode", run.mode, "roadmap: undeformed, adapted or both (both: preoperative faint, adapted over it)")
      ->check(CLI::IsMember({"undeformed", "adapted", "both"}))
      ->capture_default_str();
  auto* rspeed = rn->add_option("--speed", run.speed, "replay speed (1 = real time)")
                     ->check(CLI::Range(session::kMinReplaySpeed, session::kMaxReplaySpeed))
                     ->capture_default_str();
  rn->add_flag("--fast", run.fast, "replay as fast as the node takes the frames")->excludes(rspeed);
  rn->add_option("--loop", run.loops, "replay loops; 0 = until interrupted")->check(CLI::NonNegativeNumber)->capture_default_str();
  rn->add_flag("--preload", run.preload,
               "with --replay: decode every frame before playing and keep them in memory (frames x width x height x 2 "
               "bytes), so the decoding (which a grabber does not do) takes no CPU from the node");
  rn->add_option("--seconds", run.seconds, "stop after this long")->check(CLI::PositiveNumber);
  rn->add_flag("!--no-progress", run.progress, "no progress bar");

  EvalCommand eval;
  auto* ev = app.add_subcommand(
      "eval",
      "The paper's evaluation (Table 1) on sessions with ground truth (e.g. from `evarnode sim session`):\n"
      "each session goes through the node's steps (device candidates, view pairs, reconstruction,\n"
      "deformation) and in every settled frame after the first adapted model the landmarks projected\n"
      "from the preoperative and from the adapted model are compared with the true ostia: Euclidean\n"
      "and vertical 2D distances in mm at the isocenter. Writes OUT/eval.json, OUT/eval.md,\n"
      "OUT/per_case.png, OUT/distribution.png, OUT/snapshots/ and OUT/devices/ (each session's last\n"
      "reconstructed device beside the true one, Slicer markups in the node's CT frame, usable as\n"
      "`deform --device`). Exit 1 when no session gave a model.");
  ev->add_option("sessions", eval.sessions, "session directories")->required()->check(CLI::ExistingDirectory);
  ev->add_option("--out", eval.out, "output directory (created)")->required();
  ev->add_flag("!--no-progress", eval.progress, "no progress bars");
  ev->add_flag("!--no-pelvis", eval.pelvis,
               "leave the models where the registration put them; by default, as the live node, where the\n"
               "scene has the pelvis's bones the pelvis is found in the fluoroscopy and the models move with it\n"
               "before they are bent (beyond the paper; docs/DEFORMATION.md, \"The pelvis\")");

  std::vector<std::string> reversed(args.rbegin(), args.rend());
  try {
    app.parse(reversed);
  } catch (const CLI::ParseError& err) {
    // --help and --version exit 0; every usage error exits 2 (CLI11 has its own codes).
    return app.exit(err) == 0 ? 0 : 2;
  }
  node::set_log_level(log_level);
  try {
    if (d->parsed()) return run_deform(deform);
    if (sc->parsed()) return run_scene(scene_cmd);
    if (px->parsed()) return run_proxies(proxies);
    if (a->parsed()) return run_arap(arap);
    if (e->parsed()) return run_example(example);
    if (pr->parsed()) return run_project(project);
    if (cv->parsed()) return run_calibrate_video(calibrate);
    if (sg->parsed()) return run_segment(segment);
    if (rc->parsed()) return run_reconstruct(reconstruct);
    if (sp->parsed()) return run_sim_patient(sim_patient);
    if (ss->parsed()) return run_sim_session(sim_session);
    if (rp->parsed()) return run_replay(replay);
    if (ex->parsed()) return run_export(export_cmd);
    if (dv->parsed()) return run_devices(devices);
    if (rd->parsed()) return run_record(record);
    if (ev->parsed()) return run_eval(eval);
    if (rn->parsed()) return run_node(run);
  } catch (const base::InputError& err) {
    node::log().error("{}", err.what());
    return 1;
  } catch (const std::exception& err) {
    node::log().error("{}", err.what());
    return 1;
  }
  return 2;
}

}  // namespace evar::app
