// The simulated booth: rig + scene + pattern → capture set (what the 4 cameras would record).
//
// World frame (see docs/capture-format.md): millimetres, right-handed, head centred near the
// origin, +y up, +z out of the face towards the front cameras, +x to the image right of a
// camera in front of the face (the subject's left). Camera and projector poses follow the
// capture set's convention: x_dev = R * x_world + T, device looks along its +z, image y down.
//
// Layers, each usable on its own:
//   Rig     the booth (cameras, projectors, sensor, lights): load_rig() from a YAML file, or
//           default_rig() (identical to tools/sim/rigs/default.yaml, checked by a test).
//   Scene   what stands in the booth: the procedural head, its pose, albedo, noise level.
//   Surface any triangle mesh with a colour (constant, per vertex or UV texture): render_views()
//           renders arbitrary surfaces (a calibration board, a plane, a sphere) through the rig.
//   Tracer  ray casting against a set of surfaces (host/raycast's, on the surfaces' meshes).
// Libraries never log; the CLI (`facescan simulate`) prints the timings.
#pragma once

#include "capture/capture_set.hpp"
#include "common/status.hpp"
#include "pattern/pattern.hpp"
#include "raycast/raycast.hpp"

#include <opencv2/core.hpp>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace facescan::sim {

// ---- the rig -------------------------------------------------------------------------------

/// A camera of the booth: its calibration (exactly what calibration.yaml will say) and its optics.
struct SimCamera {
	std::string name;
	CameraModel model;	      // K, dist (k1 k2 p1 p2 k3), R, T (world → camera), size
	double focus_mm = 550;	      // distance along the optical axis that is sharp
	double blur_px = 0.5;	      // Gaussian sigma of the lens at focus (pixels)
	double defocus_px_per_100mm = 0.8; // extra sigma per 100 mm away from focus (pixels)
	double exposure = 1.0;	      // multiplies the scene radiance before the sensor
};

/// A projector: a pinhole throwing the slide (no lens distortion), with defocus.
struct SimProjector {
	std::string name;
	cv::Matx33d K = cv::Matx33d::eye();
	cv::Matx33d R = cv::Matx33d::eye(); // world → projector
	cv::Vec3d T = {0, 0, 0};
	cv::Size size = {1024, 768};
	/// Sensor value (linear, 1 = full well at exposure 1) that a white slide pixel (255)
	/// produces on a white Lambertian surface (albedo 1) facing the projector at 500 mm.
	double power = 1.0;
	double focus_mm = 600;
	double blur_px = 0.6;		    // slide pixels, at focus
	double defocus_px_per_100mm = 1.5;  // slide pixels per 100 mm away from focus
	double gamma = 2.2;		    // slide value → light: (v/255)^gamma
	/// A mask on the slide: the polygon (slide pixels, pixel centres at integers) through which
	/// light passes; the rest of the slide is black. Empty = the whole slide.
	std::vector<cv::Point2d> mask;
	cv::Vec3d centre() const { return -(R.t() * T); }
};

/// The sensor and its image pipeline (shared by all cameras).
struct SensorModel {
	double full_well_e = 9000;	// electrons at linear value 1 (shot noise)
	double read_noise_e = 6;	// electrons RMS
	int adc_bits = 12;
	double gamma = 2.2;		// output encoding: v = linear^(1/gamma)
	/// Colour crosstalk of the filter array: raw RGB = crosstalk * scene RGB (rows R, G, B).
	cv::Matx33d crosstalk = cv::Matx33d(0.86, 0.11, 0.03, 0.08, 0.84, 0.08, 0.03, 0.12, 0.85);
	bool bayer = true;		// RGGB mosaic, then OpenCV's demosaic
	double noise_scale = 1.0;	// multiplies shot and read noise (scenes raise it)
};

/// A soft light for the texture frames (projectors off): direction from the head, no shadows.
struct DiffuseLight {
	double azimuth_deg = 0, elevation_deg = 0;
	double intensity = 0.5;		// sensor value on a white surface facing it
};

struct Lighting {
	double ambient_pattern = 0.03;	// room light in the pattern frames (white surface value)
	double ambient_texture = 0.12;	// uniform part of the diffuse light in the texture frames
	std::vector<DiffuseLight> lights; // the texture frames' soft boxes
};

struct Rig {
	std::vector<SimCamera> cameras;
	std::vector<SimProjector> projectors;
	SensorModel sensor;
	Lighting lighting;
	/// Rendering samples per pixel along each axis (1 = one ray at the pixel centre; 2 = 2x2).
	int supersample = 1;
};

/// The rig of tools/sim/rigs/default.yaml, built in so that the CLI needs no file.
Rig default_rig();

/// Reads a rig file (OpenCV FileStorage YAML; keys in docs/simulator.md). Devices are placed by
/// azimuth/elevation/distance around a target point; missing keys take default_rig()'s values.
/// -ENOENT missing file, -EINVAL malformed (the message names the file and the key).
Status load_rig(const std::string &path, Rig *ret_rig);

/// Scales every camera's resolution by `scale` (0 < scale <= 4), K scaled to match
/// (pixel centres preserved), blur in pixels scaled too. Projectors are not changed.
Status scale_rig(double scale, Rig *rig);

/// A camera or projector pose looking from `eye` at `target` with world +y up (rolled by
/// roll_deg about the viewing axis). Returns R (world → device) and T.
void look_at(const cv::Vec3d &eye, const cv::Vec3d &target, double roll_deg, cv::Matx33d *ret_R,
	     cv::Vec3d *ret_T);
/// Position at azimuth (about +y, 0 = +z, positive towards +x), elevation and distance from target.
cv::Vec3d orbit_position(const cv::Vec3d &target, double azimuth_deg, double elevation_deg,
			 double distance_mm);

/// The calibration a capture set records for this rig.
Calibration rig_calibration(const Rig &rig);

/// The rig's projectors as pinhole models (no distortion), for the evaluation's "lit" test.
std::vector<CameraModel> projector_models(const Rig &rig);
/// The rig's slide masks, one per projector (empty polygon = the whole slide lights).
std::vector<std::vector<cv::Point2d>> projector_masks(const Rig &rig);

/// Writes `rig` as a rig file (every device by R and T, so load_rig() gives it back exactly),
/// atomically. `booth_text`, when not empty, is YAML placed under a top-level `booth:` key
/// (load_rig() ignores it: it records how a random booth was drawn).
Status write_rig(const std::string &path, const Rig &rig, const std::string &booth_text = "");

// ---- geometry --------------------------------------------------------------------------------

/// A triangle mesh. Optional per-vertex arrays are either empty or vertices.size() long.
struct Mesh {
	std::vector<cv::Vec3f> vertices;	// mm
	std::vector<cv::Vec3i> triangles;	// counter-clockwise seen from outside
	std::vector<cv::Vec3f> normals;		// optional smooth normals (else flat)
	std::vector<cv::Vec3f> colors;		// optional linear albedo per vertex (RGB, 0..1)
	std::vector<cv::Vec2f> uv;		// optional texture coordinates (0..1, v down)
};

/// What a surface looks like. Albedo precedence: texture (needs mesh.uv), mesh.colors, albedo.
struct Surface {
	Mesh mesh;
	cv::Vec3f albedo = {0.5f, 0.5f, 0.5f}; // linear RGB
	cv::Mat texture;	// optional 8-bit BGR image (sRGB-encoded), sampled bilinearly at uv
	float specular = 0;	// Blinn-Phong sheen, fraction of the diffuse light
	float shininess = 30;
	int id = 0;		// reported in the truth's surface map (0 is reserved for "nothing")
};

/// Applies x' = R x + t to vertices (and R to normals).
void transform_mesh(const cv::Matx33d &R, const cv::Vec3d &t, Mesh *mesh);
/// A w × h rectangle in the z = 0 plane centred at the origin, facing +z, uv over the whole.
Mesh make_plane(double width_mm, double height_mm, int subdivisions = 1);
/// A UV sphere with smooth normals.
Mesh make_sphere(const cv::Vec3d &centre, double radius_mm, int rings = 96, int segments = 192);
/// Writes a binary little-endian PLY (vertices, normals when present, faces).
Status write_ply(const std::string &path, const Mesh &mesh);

// ---- the scene ---------------------------------------------------------------------------------

/// Anatomy of the procedural head. The defaults are the canonical head; factors multiply a
/// canonical measure, *_mm are offsets. Ranges: head_shape_ranges() (docs/simulator.md).
struct HeadShape {
	double width = 1, height = 1, depth = 1;	// whole head scale along x, y, z
	double nose_length = 1;			// bridge to tip, vertically
	double nose_width = 1;			// alae spacing and nose radii
	double nose_projection = 1;		// how far the tip stands out of the face
	double chin = 1;			// chin size and projection
	double cheeks = 1;			// cheek fullness
	double lips = 1;			// lip fullness (height and projection)
	double eye_sockets = 1;			// eye-socket depth
	double ear_up_mm = 0, ear_back_mm = 0;	// ear position offset (both ears)
	double asymmetry = 0;			// subject's left side wider by this fraction (- = right)
	double nose_deviation_mm = 0;		// nose tip shifted along +x
};

/// One HeadShape member with the range random_head_shape() draws it from (make_head refuses
/// values outside).
struct HeadShapeRange {
	const char *name;
	double HeadShape::*member;
	double lo, hi;
};
const std::vector<HeadShapeRange> &head_shape_ranges();

/// A head drawn uniformly from head_shape_ranges(), deterministic for `head_seed` (independent
/// of the sensor noise seed).
HeadShape random_head_shape(uint64_t head_seed);

/// How the head looks, beyond its anatomy. The defaults are the canonical head's appearance
/// (skin tone itself is Scene::skin). Ranges: head_look_ranges() (docs/simulator.md).
struct HeadLook {
	double blotches = 1;		// strength of the 4 / 14 mm skin blotches (1 = canonical +-8 %)
	double freckles = 0;		// freckle density on nose, cheeks and forehead (0 none, 1 many)
	double freckle_darkness = 0.35;	// albedo drop at a freckle's centre
	double redness = 1;		// cheek / nose-tip flush
	double brow_darkness = 1;	// 1 = canonical (near-black hair), 0 = as light as the skin
	double brow_width = 1;		// brow thickness factor
	double lip_red = 1;		// lip colour: 0 = skin, 1 = canonical, 1.5 = strong red
	double lip_darkness = 1;	// lip albedo factor on top of the colour
	double stubble = 0;		// beard shadow on jaw, chin and upper lip (0 none, 1 dark)
	double hairline_mm = 0;		// hairline raised (+) or lowered (-) from the canonical
	double hair_fringe = 0;		// wisps of hair below the hairline (0 none, 1 a ragged band)
	cv::Vec3f hair = {0.045f, 0.032f, 0.024f}; // hair albedo (linear RGB)
	bool shoulders = false;		// neck continues into shoulders and an upper chest
};

/// One scalar HeadLook member with its range (random_head_appearance() draws inside; make_head refuses
/// values outside).
struct HeadLookRange {
	const char *name;
	double HeadLook::*member;
	double lo, hi;
};
const std::vector<HeadLookRange> &head_look_ranges();

/// A head's whole appearance drawn from the widened family: skin tone from light to dark, the
/// HeadLook scalars uniformly from their ranges, hair colour, and shoulders. Deterministic for
/// the seed (and independent of random_head_shape's draw for the same seed).
struct HeadAppearance {
	cv::Vec3f skin;
	HeadLook look;
	double skin_tone = 0;		// 0 lightest .. 1 darkest of the range (for the record)
};
HeadAppearance random_head_appearance(uint64_t head_seed);

struct HeadSpec {
	double cell_mm = 1.4;	// grid step of the implicit surface (smaller = more triangles)
	uint32_t seed = 1;	// skin blotches
	HeadShape shape;	// anatomy (default: the canonical head)
	HeadLook look;		// appearance (default: the canonical head's)
	/// Non-empty: the head is the scanned one prepared in this directory
	/// (`tools/install-web-deps.sh scan`), painted with `look` and `seed`; `shape` and
	/// look.shoulders are not used. -ENOENT from make_head when the directory has no scan.
	std::string scan_dir;
};

/// The procedural head in head coordinates (mm, face towards +z, +y up, centred near the
/// origin): cranium, forehead, eye sockets with eyes, brows, nose, cheeks, lips, chin, jaw, ears,
/// neck. Smooth normals and per-vertex skin albedo (hair, brows, lips, eyes darker/redder),
/// scaled by `skin` (the albedo of plain cheek skin, linear RGB). -EINVAL when cell_mm or a
/// shape parameter is out of range.
Status make_head(const HeadSpec &spec, const cv::Vec3f &skin, Mesh *ret_mesh);

struct Scene {
	std::string name = "default";
	double yaw_deg = 0, pitch_deg = 0;	// head rotation about +y, then +x
	double roll_deg = 0;			// ... after a roll about +z (applied first)
	cv::Vec3d position = {0, 0, 0};		// head origin in world mm
	cv::Vec3f skin = {0.62f, 0.43f, 0.34f}; // linear albedo of cheek skin
	double noise_scale = 1.0;		// multiplies the rig sensor's noise
	double backdrop_radius_mm = 900;	// the booth's dark wall: a cylinder about +y; NAN = none
	cv::Vec3f backdrop_albedo = {0.04f, 0.04f, 0.045f};
	HeadSpec head;
};

/// Named scenes: "default", "turned" (head yawed 15°), "noisy" (4x sensor noise),
/// "dark" (darker skin albedo). -EINVAL for an unknown name (the message lists the names).
Status scene_by_name(const std::string &name, Scene *ret_scene);
std::vector<std::string> scene_names();

// ---- rendering ---------------------------------------------------------------------------------

/// Ground truth of one rendered view, per camera pixel (at the pixel centre).
struct ViewTruth {
	cv::Mat depth;		// CV_32F, camera z in mm; 0 where the ray hit nothing
	cv::Mat surface;	// CV_8U, Surface::id hit (0 = nothing)
	/// CV_32FC2 slide coordinates (pixels) of the brightest projector lighting the point, and
	/// CV_8S its index (-1 = no projector light: off-slide, back-facing or shadowed).
	cv::Mat slide_xy, projector;
};

struct RenderOptions {
	bool pattern = true;	  // render the pattern frames (projectors on)
	bool texture = true;	  // render the texture frames (projectors off, diffuse light)
	bool noise = true;	  // false: noise-free sensor (for geometric tests)
	bool truth = false;	  // fill ViewTruth
	std::vector<bool> projectors_on; // empty = all on
};

struct RenderResult {
	std::vector<cv::Mat> frames;	// per camera, 8-bit BGR, pattern frames (if requested)
	std::vector<cv::Mat> textures;	// per camera, 8-bit BGR, texture frames (if requested)
	std::vector<ViewTruth> truth;	// per camera (if requested)
};

/// Renders every camera of the rig looking at `surfaces`, lit by the projectors throwing
/// `slide` (8-bit BGR, resized to each projector if it differs) and by the rig's lights.
/// Deterministic for a seed (any thread count). -EINVAL on an empty rig, an empty slide when
/// pattern frames are requested, or a malformed mesh (index out of range, bad array sizes).
Status render_views(const Rig &rig, const std::vector<Surface> &surfaces, const cv::Mat &slide,
		    const RenderOptions &options, uint64_t seed, RenderResult *ret_result);

/// Ground truth of a simulated scan.
struct SimTruth {
	Mesh head;			// the head in world mm (as written to ground_truth.ply)
	/// Per vertex of `head`: 1 on the face (face_region(): hairline to chin, ear to ear), what
	/// the face completeness is over; written as ground_truth_face.ply.
	std::vector<char> face;
	std::vector<ViewTruth> views;	// per camera, when SimOptions::truth_maps
	/// The projectors as pinhole models (projector_models(rig)): which truth points were lit,
	/// for scoring completeness without knowing the rig file the set was rendered with.
	std::vector<CameraModel> projectors;
	/// Per projector, its slide mask (projector_masks(rig)); all empty when nothing is masked.
	std::vector<std::vector<cv::Point2d>> projector_masks;
	/// The true calibration of the cameras the set was rendered through, when the set's
	/// calibration.yaml was written with an error (random booths); empty otherwise.
	Calibration true_calibration;
	double render_seconds = 0;	// wall time of the render (for the CLI and the bench)
};

struct SimOptions {
	bool truth_maps = false;	// fill SimTruth::views
	bool texture_frames = true;
};

/// The booth: renders the scene's head (and backdrop) through the rig lit by `pattern`'s slide.
/// Fills a complete capture set (calibration from the rig, frames, textures, meta with
/// scan_id "sim-<scene>-<seed>" and the pattern id) and the truth. Either output may be null.
Status simulate(const Rig &rig, const Scene &scene, const Pattern &pattern, uint64_t seed,
		CaptureSet *ret_set, SimTruth *ret_truth, const SimOptions &options = SimOptions());

/// A contact sheet: the pattern frames in a row above the texture frames, each scaled to
/// `tile_width` pixels wide, camera names written on the tiles. 8-bit BGR.
cv::Mat contact_sheet(const CaptureSet &set, int tile_width);

/// Writes the capture set plus the ground truth into `dir`: ground_truth.ply (the head, world mm),
/// ground_truth_projectors.yaml (the projectors, in calibration.yaml's format, plus
/// `cam{j}_slide_mask: [x0, y0, x1, y1, ...]` for every masked projector j) and, when
/// truth.true_calibration has cameras, ground_truth_calibration.yaml (the cameras as rendered).
Status write_simulated_set(const std::string &dir, const CaptureSet &set, const SimTruth &truth);

// ---- random booths -----------------------------------------------------------------------------

/// A closed interval a random booth draws from (uniformly).
struct Interval {
	double lo = 0, hi = 0;
};

/// The ranges random_booth() draws from; every one is listed in docs/simulator.md. Angles in
/// degrees, lengths in mm, the world frame of this header (head nominally at the origin).
struct BoothRanges {
	/// Cameras, left to right (cam0 at the subject's right, -x). Consecutive cameras are
	/// recon's stereo pairs: their azimuths differ by cam_gap_deg at most, so each pair sees
	/// a common part of the face.
	Interval cam_azimuth_deg[4] = {{-70, -40}, {-32, -8}, {8, 32}, {40, 70}};
	Interval cam_gap_deg = {18, 55};
	Interval cam_elevation_deg = {-10, 15};
	Interval cam_distance_mm = {450, 700};
	Interval cam_roll_deg = {-3, 3};
	Interval cam_target_jitter_mm = {-15, 15};	// each axis, around (0, -10, 40)
	/// Focal length such that 240 mm (crown to chin) fills this fraction of the image height.
	Interval cam_fill = {0.55, 0.85};
	Interval cam_width_px = {1440, 1760};		// height = width / aspect (4:3, 5:4 or 16:10)
	Interval cam_principal_offset = {-0.02, 0.02};	// fraction of the size, each axis
	Interval cam_k1 = {-0.15, 0.05}, cam_k2 = {-0.05, 0.15}, cam_p = {-0.001, 0.001};
	Interval cam_exposure = {0.8, 1.25};
	Interval cam_blur_px = {0.35, 0.7};
	/// Projectors, left / centre / right.
	Interval proj_azimuth_deg[3] = {{-65, -28}, {-12, 12}, {28, 65}};
	Interval proj_elevation_deg = {0, 25};
	Interval proj_distance_mm = {450, 800};
	/// Focal length such that the pattern's cell pitch measures this on a surface at the
	/// projector's target distance (the slide is 1024 x 768, the default pattern's pitch).
	Interval proj_pitch_mm = {6, 20};
	/// Roll: a quarter turn (0, 90, 180 or 270, equally likely) plus this.
	Interval proj_roll_extra_deg = {-10, 10};
	/// Aim points (x per projector, y and z shared) when the projectors overlap.
	Interval proj_aim_x_mm[3] = {{-75, -25}, {-15, 15}, {25, 75}};
	Interval proj_aim_y_mm = {-45, 5};
	Interval proj_aim_z_mm = {20, 70};
	/// Light on the face: projector power such that a white surface facing it at its target
	/// distance gives this sensor value.
	Interval proj_face_power = {1.1, 2.0};
	/// Masked booths (probability masked_probability): each projector lights only its zone of
	/// the face, the zones split by vertical planes x = left / right (booth frame, at the face
	/// depth z = 60 mm), each widened by the overlap on both sides.
	double masked_probability = 0.5;
	Interval zone_left_mm = {-45, -15}, zone_right_mm = {15, 45};
	Interval zone_overlap_mm = {0, 8};
	/// A masked projector aims inside its zone: this far beyond the zone boundary (outer
	/// projectors), or this far off the zone centre (the centre one).
	Interval zone_aim_outer_mm = {15, 45}, zone_aim_centre_mm = {-8, 8};
	/// Lighting and sensor.
	Interval ambient_pattern = {0.01, 0.08}, ambient_texture = {0.06, 0.18};
	Interval softbox_azimuth_deg = {20, 50}, softbox_elevation_deg = {5, 35};
	Interval softbox_intensity = {0.3, 0.6}, toplight_intensity = {0, 0.3};
	Interval noise_scale = {0.7, 3}, read_noise_e = {3, 10}, full_well_e = {6000, 12000};
	/// The head's pose: offset from the nominal place on each axis, then turned.
	Interval head_offset_mm = {-20, 20};
	Interval head_yaw_deg = {-10, 10}, head_pitch_deg = {-10, 10}, head_roll_deg = {-6, 6};
	/// The written calibration's error: per camera, the RMS displacement (pixels) of the
	/// head's points between the true and the written calibration.
	Interval calibration_error_px = {0.2, 0.4};
};
const BoothRanges &booth_ranges();

/// A booth drawn at random, and what was drawn (for booth.yaml and the tests).
struct RandomBooth {
	uint64_t seed = 0;
	Rig rig;			// the true rig: renders the scene
	bool masked = false;
	double zone_left_mm = 0, zone_right_mm = 0, zone_overlap_mm = 0;
	std::vector<double> cam_azimuth_deg, cam_elevation_deg, cam_distance_mm;
	std::vector<double> proj_azimuth_deg, proj_elevation_deg, proj_distance_mm, proj_roll_deg;
	std::vector<double> proj_pitch_mm;	// cell pitch on a surface at the projector's target
	cv::Vec3d head_offset_mm = {0, 0, 0};
	double head_yaw_deg = 0, head_pitch_deg = 0, head_roll_deg = 0, noise_scale = 1;
	std::vector<double> calibration_error_px; // per camera, the target of perturb_calibration
};

/// Draws a booth from booth_ranges(), deterministic for the seed. `slide_pitch_px` is the
/// pattern's cell pitch on the 1024 x 768 slide (Pattern::pitch), which the projector focal
/// lengths are chosen for. -EINVAL when it is not positive.
Status random_booth(uint64_t seed, double slide_pitch_px, RandomBooth *ret_booth);

/// The slide mask that confines projector `p` to the zone x_lo_mm <= x <= x_hi_mm of the booth
/// (either may be infinite): the slide clipped by the images of the vertical lines x = x_lo / x_hi
/// at the face's depth (z = 60 mm). -EINVAL when nothing of the slide is left.
Status zone_mask(const SimProjector &p, double x_lo_mm, double x_hi_mm, std::vector<cv::Point2d> *ret_mask);

/// Places a scene's head as the booth drew it (offset and turn; the rest of the scene stays).
void apply_head_pose(const RandomBooth &booth, Scene *scene);

/// A calibration with the error of a good one: each camera's K, dist, R and T moved along a
/// random direction (seeded) scaled so that `points` (world mm) reproject, RMS over the
/// points in front of the camera and inside its image, `rms_px[i]` pixels away from where the
/// true camera i puts them. `ret_rms_px` gets the RMS reached (within 2 % of the target).
/// -EINVAL when sizes disagree or a camera sees fewer than 20 of the points.
Status perturb_calibration(const Calibration &truth, const std::vector<double> &rms_px,
			   const std::vector<cv::Point3d> &points, uint64_t seed, Calibration *ret_calibration,
			   std::vector<double> *ret_rms_px);

/// RMS pixel distance between where two calibrations of one camera put `points` (those in front
/// of both and inside `a`'s image); -1 when fewer than 20 qualify.
double reprojection_rms(const CameraModel &a, const CameraModel &b, const std::vector<cv::Point3d> &points);

/// The booth as YAML text for the `booth:` section of booth.yaml (what was drawn, and the
/// calibration error reached).
std::string booth_yaml(const RandomBooth &booth, const std::vector<double> &calibration_rms_px);

// ---- face coverage -----------------------------------------------------------------------------

/// Per vertex of a head made by make_head(spec) (head coordinates, before any pose): 1 on the
/// face as the issue asks it covered: from the hairline to under the chin, ear to ear (in front
/// of the ears), the under-side of the jaw and the neck excluded.
std::vector<char> face_region(const HeadSpec &spec, const Mesh &head);

struct FaceCoverage {
	int face_points = 0;
	double lit = 0;			// fraction of face points some projector lights (mask included)
	double lit_twice = 0;		// ... that two or more projectors light
	double paired = 0;		// ... that both cameras of a consecutive pair see
	double lit_and_paired = 0;	// ... lit and seen by a consecutive pair: what recon can reach
};

/// Where the rig's light and stereo pairs reach the face of `scene`'s head in its pose, by ray
/// casting (no rendering): a projector lights a point it faces (cos >= 0.1) unshadowed, on its
/// slide and inside its mask; a camera sees a point unoccluded, in its image, within 72 deg of
/// the normal (cos >= 0.3). -EINVAL as make_head.
Status face_coverage(const Rig &rig, const Scene &scene, FaceCoverage *ret_coverage);

// ---- ray casting -------------------------------------------------------------------------------

/// The project's ray caster (host/raycast): surface = index into the surfaces vector.
using Hit = raycast::Hit;
using Tracer = raycast::Tracer;
/// Builds `tracer` over the surfaces' meshes (copied). -EINVAL on a malformed mesh, -ENOMEM /
/// -EIO when Embree fails.
Status build_tracer(const std::vector<Surface> &surfaces, Tracer *tracer);

/// The world-space ray through a (distorted) pixel of a camera: centre and unit direction.
void pixel_ray(const CameraModel &camera, const cv::Point2d &pixel, cv::Vec3d *ret_origin,
	       cv::Vec3d *ret_dir);

} // namespace facescan::sim
