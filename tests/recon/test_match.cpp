// Stage 4: correspondence on a synthetic stereo pair with known geometry. Three copies of the slide
// lie side by side on a face-like cylinder (three projectors, one slide); both cameras see parts
// of all three. Every match must pair the same square of the same copy.
#include "recon/image_stages.hpp"

#include "cmocka.hpp"

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>

using namespace facescan;
using namespace facescan::recon;

static CameraModel camera_at(double azimuth_deg, const cv::Vec3d &target, double distance)
{
	double a = azimuth_deg * M_PI / 180;
	cv::Vec3d eye = target + distance * cv::Vec3d(std::sin(a), 0, std::cos(a));
	cv::Vec3d z = cv::normalize(target - eye);
	cv::Vec3d x = cv::normalize(z.cross(cv::Vec3d(0, 1, 0)));
	cv::Vec3d y = z.cross(x); // image y points down
	CameraModel c;
	c.R = cv::Matx33d(x[0], x[1], x[2], y[0], y[1], y[2], z[0], z[1], z[2]);
	c.T = -(c.R * eye);
	c.K = cv::Matx33d(2000, 0, 801.5, 0, 2002, 598.5, 0, 0, 1);
	c.dist = {-0.06, 0.09, 0.0004, -0.0003, 0};
	c.size = {1600, 1200};
	return c;
}

struct Scene {
	std::vector<CameraDetections> dets;	// per camera
	std::vector<std::vector<int>> copy_of;	// per camera, per square: which copy
	std::vector<std::vector<int>> cell_of;	// per camera, per square: its true cell
};

// The slide's copy k on a cylinder of radius 120 mm about the y axis (front at z = 40 mm).
static cv::Vec3d on_face(const Pattern &p, int copy, const cv::Point2d &slide, const double *lift)
{
	const double mm = 0.2, radius = 120;
	double theta = (copy - 1) * 0.95 + (slide.x - p.slide.width / 2.0) * mm / radius;
	double y = -(slide.y - p.slide.height / 2.0) * mm + lift[copy];
	return {radius * std::sin(theta), y, radius * std::cos(theta) - 80};
}

static Scene make_scene(const Pattern &p, const std::vector<CameraModel> &cams, const double *lift,
			double noise_px, uint64_t seed)
{
	Scene s;
	cv::RNG rng(seed);
	const CodeMatrix &m = p.matrix;
	for (const CameraModel &cam : cams) {
		CameraDetections d;
		std::vector<int> copies;
		cv::Vec3d eye = cam.centre();
		std::vector<std::vector<int>> index(3, std::vector<int>(size_t(m.rows() * m.cols()), -1));
		for (int copy = 0; copy < 3; copy++)
			for (int r = 0; r < m.rows(); r++)
				for (int c = 0; c < m.cols(); c++) {
					cv::Rect2d rc = p.cell_rect(r, c);
					std::vector<cv::Point3d> world = {
						on_face(p, copy, {rc.x, rc.y}, lift),
						on_face(p, copy, {rc.x + rc.width, rc.y}, lift),
						on_face(p, copy, {rc.x + rc.width, rc.y + rc.height}, lift),
						on_face(p, copy, {rc.x, rc.y + rc.height}, lift)};
					cv::Vec3d ctr = on_face(p, copy, {rc.x + rc.width / 2, rc.y + rc.height / 2}, lift);
					cv::Vec3d normal(ctr[0], 0, ctr[2] + 80);
					if (normal.dot(eye - ctr) < 0.35 * cv::norm(normal) * cv::norm(eye - ctr))
						continue; // grazing or facing away
					std::vector<cv::Point2d> img;
					cv::Mat rvec;
					cv::Rodrigues(cv::Mat(cam.R), rvec);
					cv::projectPoints(world, rvec, cv::Mat(cam.T), cv::Mat(cam.K), cv::Mat(cam.dist), img);
					Square q;
					bool inside = true;
					for (size_t k = 0; k < 4; k++) {
						q.corners[k] = img[k] + cv::Point2d(rng.gaussian(noise_px), rng.gaussian(noise_px));
						inside = inside && img[k].x > 0 && img[k].y > 0 && img[k].x < 1600 && img[k].y < 1200;
					}
					if (!inside)
						continue;
					q.has_corners = true;
					q.centroid = 0.25 * (q.corners[0] + q.corners[1] + q.corners[2] + q.corners[3]);
					std::vector<cv::Point2f> outline(q.corners.begin(), q.corners.end());
					q.area = cv::contourArea(outline);
					q.cell = r * m.cols() + c;
					q.letter = m.at(r, c);
					index[size_t(copy)][size_t(q.cell)] = int(d.squares.size());
					d.squares.push_back(q);
					copies.push_back(copy);
				}
		const int dr[4] = {-1, 0, 0, 1}, dc[4] = {0, -1, 1, 0};
		for (size_t i = 0; i < d.squares.size(); i++) {
			int cell = d.squares[i].cell, r = cell / m.cols(), c = cell % m.cols();
			for (int k = 0; k < 4; k++) {
				int rr = r + dr[k], cc = c + dc[k];
				if (rr >= 0 && cc >= 0 && rr < m.rows() && cc < m.cols())
					d.squares[i].neighbours[size_t(k)] = index[size_t(copies[i])][size_t(rr * m.cols() + cc)];
			}
		}
		d.camera = int(s.dets.size());
		s.dets.push_back(d);
		s.copy_of.push_back(copies);
		std::vector<int> cells;
		for (const Square &q : d.squares)
			cells.push_back(q.cell);
		s.cell_of.push_back(cells);
	}
	return s;
}

struct Outcome {
	int centroids = 0, corners = 0, wrong = 0, possible = 0;
};

static Outcome check(const Scene &s, const PairMatches &pm)
{
	Outcome o;
	for (const PointMatch &m : pm.matches) {
		const Square &qa = s.dets[0].squares[size_t(m.square_a)];
		const int cell_a = s.cell_of[0][size_t(m.square_a)], cell_b = s.cell_of[1][size_t(m.square_b)];
		bool right = cell_a == cell_b && s.copy_of[0][size_t(m.square_a)] == s.copy_of[1][size_t(m.square_b)];
		o.wrong += !right;
		if (m.feature == kCentroid)
			o.centroids++;
		else
			o.corners++;
		if (m.cell >= 0) // grown matches of two squares without a code word carry no cell
			assert_int_equal(m.cell, cell_a);
		cv::Point2d want_a = m.feature == kCentroid ? qa.centroid : qa.corners[size_t(m.feature - 1)];
		assert_true(cv::norm(want_a - m.a) < 1e-9);
	}
	for (size_t i = 0; i < s.dets[0].squares.size(); i++)
		for (size_t j = 0; j < s.dets[1].squares.size(); j++)
			o.possible += s.cell_of[0][i] == s.cell_of[1][j] && s.copy_of[0][i] == s.copy_of[1][j];
	return o;
}

// Two cameras 40° apart, 550 mm from the cylinder, the three copies thrown from different
// heights; 0.05 px of corner noise.
struct Stereo {
	Pattern p;
	std::vector<CameraModel> cams;
	Scene s;
};

static Stereo stereo_scene(uint64_t seed)
{
	Stereo st;
	assert_true(default_pattern(SlideSpec{}, &st.p).ok());
	const cv::Vec3d target(0, -10, 40);
	st.cams = {camera_at(-20, target, 550), camera_at(20, target, 550)};
	const double lift[3] = {-6, 0, 7}; // projectors at different heights
	st.s = make_scene(st.p, st.cams, lift, 0.05, seed);
	return st;
}

// Removes squares from camera c's detections (as if never detected), keeping the links and the
// truth of the others.
static void remove_squares(Scene *s, size_t c, const std::vector<char> &gone)
{
	std::vector<int> index(gone.size(), -1);
	CameraDetections kept;
	kept.camera = s->dets[c].camera;
	std::vector<int> copies, cells;
	for (size_t i = 0; i < gone.size(); i++)
		if (!gone[i]) {
			index[i] = int(kept.squares.size());
			kept.squares.push_back(s->dets[c].squares[i]);
			copies.push_back(s->copy_of[c][i]);
			cells.push_back(s->cell_of[c][i]);
		}
	for (Square &q : kept.squares)
		for (int &j : q.neighbours)
			j = j >= 0 ? index[size_t(j)] : -1;
	s->dets[c] = kept;
	s->copy_of[c] = copies;
	s->cell_of[c] = cells;
}

static void matches_pair_the_same_copy_only(void **)
{
	Stereo st = stereo_scene(3);
	const Pattern &p = st.p;
	const std::vector<CameraModel> &cams = st.cams;
	Scene &s = st.s;
	PairMatches pm;
	assert_true(match_pair(s.dets[0], s.dets[1], cams[0], cams[1], p, MatchParams{}, &pm).ok());
	Outcome o = check(s, pm);
	std::printf("stereo pair: %d of %d square matches, %d corner matches, %d wrong; rejected %d "
		    "epipolar, %d ambiguous\n",
		    o.centroids, o.possible, o.corners, o.wrong, pm.rejected_epipolar, pm.rejected_ambiguous);
	assert_int_equal(o.wrong, 0);
	assert_true(o.centroids >= int(0.95 * o.possible));
	assert_true(o.corners >= 4 * o.centroids - 4);
	assert_true(pm.rejected_epipolar > 0); // the other copies of each cell were seen and refused
	assert_int_equal(pm.cam_a, 0);
	assert_int_equal(pm.cam_b, 1);

	// A square moved off its epipolar line is refused, and nothing else changes.
	Scene moved = s;
	int victim = -1;
	for (const PointMatch &m : pm.matches)
		if (m.feature == kCentroid) {
			victim = m.square_b;
			break;
		}
	assert_true(victim >= 0);
	Square &q = moved.dets[1].squares[size_t(victim)];
	q.centroid.y += 12;
	for (auto &c : q.corners)
		c.y += 12;
	PairMatches pm2;
	assert_true(match_pair(moved.dets[0], moved.dets[1], cams[0], cams[1], p, MatchParams{}, &pm2).ok());
	Outcome o2 = check(moved, pm2);
	assert_int_equal(o2.wrong, 0);
	assert_int_equal(o2.centroids, o.centroids - 1);
	for (const PointMatch &m : pm2.matches)
		assert_int_not_equal(m.square_b, victim);

	// Copies exactly side by side at one height: a wrong copy can share the epipolar lines;
	// whatever is ambiguous must be refused, never mismatched.
	const double flat[3] = {0, 0, 0};
	Scene aligned = make_scene(p, cams, flat, 0.05, 4);
	PairMatches pm3;
	assert_true(match_pair(aligned.dets[0], aligned.dets[1], cams[0], cams[1], p, MatchParams{}, &pm3).ok());
	Outcome o3 = check(aligned, pm3);
	std::printf("aligned copies: %d of %d square matches, %d wrong, %d ambiguous\n", o3.centroids,
		    o3.possible, o3.wrong, pm3.rejected_ambiguous);
	assert_int_equal(o3.wrong, 0);

	// Bad calibration is an error, not an empty result.
	CameraModel bad = cams[1];
	bad.K = cv::Matx33d::zeros();
	assert_false(match_pair(s.dets[0], s.dets[1], cams[0], bad, p, MatchParams{}, &pm).ok());
}

// Squares whose code word could not be read (no letter: a projector seam, a dim or border
// square; a wrong letter; flagged irregular in one view) are still matched by growing along
// both grids from their decoded neighbours — and never to the wrong square.
static void grows_to_squares_without_code(void **)
{
	Stereo st = stereo_scene(5);
	const Pattern &p = st.p;
	const std::vector<CameraModel> &cams = st.cams;
	Scene &s = st.s;
	cv::RNG rng(11);
	int erased = 0, wrong_letter = 0;
	for (CameraDetections &d : s.dets)
		for (Square &q : d.squares) {
			const double u = rng.uniform(0.0, 1.0);
			if (u < 0.25) { // code unread
				q.cell = -1;
				q.letter = u < 0.15 ? -1 : q.letter;
				erased++;
			} else if (u < 0.28) { // bent over a curve in this view: no corners
				q.irregular = true;
				q.has_corners = false;
			}
		}
	// A square whose letter contradicts its partner's is a different square: never grown.
	for (Square &q : s.dets[1].squares)
		if (q.cell < 0 && q.letter >= 0 && wrong_letter < 20) {
			q.letter = (q.letter + 1) % p.matrix.letters();
			wrong_letter++;
		}
	// Two squares run together in a projector seam, or one cut by a projector's frame edge, are
	// irregular in both views: still matched, by their centroids.
	int both_irregular = 0;
	for (size_t i = 0; i < s.dets[0].squares.size(); i += 13)
		for (size_t j = 0; j < s.dets[1].squares.size(); j++)
			if (s.cell_of[0][i] == s.cell_of[1][j] && s.copy_of[0][i] == s.copy_of[1][j]) {
				for (Square *q : {&s.dets[0].squares[i], &s.dets[1].squares[j]}) {
					q->irregular = true;
					q->has_corners = false;
				}
				both_irregular++;
			}
	// Grid links broken around some squares (a nostril, a lip): only guided matching reaches them.
	for (CameraDetections &d : s.dets)
		for (size_t i = 0; i < d.squares.size(); i += 9) {
			for (int &j : d.squares[i].neighbours)
				if (j >= 0) {
					for (int &back : d.squares[size_t(j)].neighbours)
						if (back == int(i))
							back = -1;
					j = -1;
				}
			d.squares[i].cell = -1;
		}
	MatchParams code_only, grow_only;
	code_only.grow.enabled = code_only.guide.enabled = code_only.seed.enabled = false;
	grow_only.guide.enabled = grow_only.seed.enabled = false;
	PairMatches before, grown, after;
	assert_true(match_pair(s.dets[0], s.dets[1], cams[0], cams[1], p, code_only, &before).ok());
	assert_true(match_pair(s.dets[0], s.dets[1], cams[0], cams[1], p, grow_only, &grown).ok());
	assert_true(match_pair(s.dets[0], s.dets[1], cams[0], cams[1], p, MatchParams{}, &after).ok());
	const Outcome ob = check(s, before), og = check(s, grown), oa = check(s, after);
	std::printf("codes erased on %d squares: %d of %d square matches by code, %d grown (%d), %d with "
		    "guided matching too (%d guided, %d pruned), %d wrong\n",
		    erased, ob.centroids, oa.possible, og.centroids, grown.grown, oa.centroids, after.guided,
		    after.pruned, oa.wrong);
	assert_int_equal(ob.wrong, 0);
	assert_int_equal(og.wrong, 0);
	assert_int_equal(oa.wrong, 0);
	assert_int_equal(before.grown + before.guided, 0);
	assert_int_equal(og.centroids, ob.centroids + grown.grown - grown.pruned);
	assert_true(after.guided > 0);
	assert_true(oa.centroids > og.centroids);
	assert_true(oa.centroids >= int(0.85 * oa.possible));
	assert_true(oa.centroids >= ob.centroids + ob.centroids / 3);
	int irregular_matched = 0;
	for (const PointMatch &m : after.matches) {
		const Square &qa = s.dets[0].squares[size_t(m.square_a)], &qb = s.dets[1].squares[size_t(m.square_b)];
		irregular_matched += qa.irregular && qb.irregular;
		assert_false(qa.letter >= 0 && qb.letter >= 0 && qa.letter != qb.letter);
		if (qa.irregular || qb.irregular) // its corners are not the slide square's: centroid only
			assert_int_equal(m.feature, kCentroid);
	}
	std::printf("irregular in both views: %d of %d matched\n", irregular_matched, both_irregular);
	assert_true(irregular_matched >= both_irregular * 3 / 4);

	// A square of b without a code word moved along its epipolar line (a centroid shifted by a
	// cut, or the wrong square in line) passes the 2-D tests but lies off the surface around it.
	Scene shifted = s;
	int moved = -1;
	for (const PointMatch &m : after.matches)
		if (m.grown && m.feature == kCentroid) {
			moved = m.square_b;
			break;
		}
	assert_true(moved >= 0);
	Square &q = shifted.dets[1].squares[size_t(moved)];
	cv::Matx33d R = cams[1].R * cams[0].R.t();
	cv::Vec3d t = cams[1].T - R * cams[0].T;
	cv::Matx33d tx(0, -t[2], t[1], t[2], 0, -t[0], -t[1], t[0], 0);
	const cv::Matx33d F = cams[1].K.inv().t() * tx * R * cams[0].K.inv();
	const Square &qa = s.dets[0].squares[size_t(std::find_if(after.matches.begin(), after.matches.end(),
							   [&](const PointMatch &m) { return m.square_b == moved; })
							  ->square_a)];
	const cv::Vec3d line = F * cv::Vec3d(qa.centroid.x, qa.centroid.y, 1);
	const cv::Point2d along = cv::Point2d(-line[1], line[0]) * (1.0 / std::hypot(line[0], line[1]));
	q.centroid += 20.0 * along; // about 4 mm off the surface at this baseline
	q.has_corners = false;
	PairMatches pruned;
	assert_true(match_pair(shifted.dets[0], shifted.dets[1], cams[0], cams[1], p, MatchParams{}, &pruned).ok());
	std::printf("a square moved 20 px along its epipolar line: %d pruned\n", pruned.pruned);
	for (const PointMatch &m : pruned.matches)
		assert_int_not_equal(m.square_b, moved);
	assert_int_equal(check(shifted, pruned).wrong, 0);

	// Moved less (about 1.8 mm off the surface): kept when neither view has the square's corners
	// (within the 2.5 mm any centroid-only square may be off) or when one view has them and its
	// area in the two views is in proportion; dropped when one view has them and the other view's
	// blob is half the size (cut there: 1.5 mm).
	const size_t partner = size_t(std::find_if(after.matches.begin(), after.matches.end(),
						  [&](const PointMatch &m) { return m.square_b == moved; })
					 ->square_a);
	struct Case {
		bool corners_in_a;
		double area_b;
		bool kept;
	};
	for (const Case &c : {Case{false, 1.0, true}, Case{true, 1.0, true}, Case{true, 0.5, false}}) {
		Scene near = s;
		Square &qb = near.dets[1].squares[size_t(moved)];
		qb.centroid += 9.0 * along;
		qb.has_corners = false;
		qb.area *= c.area_b;
		near.dets[0].squares[partner].has_corners = c.corners_in_a;
		PairMatches pm;
		assert_true(match_pair(near.dets[0], near.dets[1], cams[0], cams[1], p, MatchParams{}, &pm).ok());
		const bool kept = std::any_of(pm.matches.begin(), pm.matches.end(),
					      [&](const PointMatch &m) { return m.square_b == moved; });
		std::printf("moved 9 px, corners in %s, area in b x%.1f: %s\n", c.corners_in_a ? "one view" : "neither view",
			    c.area_b, kept ? "kept" : "pruned");
		assert_true(kept == c.kept);
	}
}

// A band of the grid no code word and no link reaches (the neck under the chin: two rows, no
// complete word, cut from the face above by the jaw's shadow) is matched by seeding growth from
// the one candidate pair whose trial growth pairs agreeing letters — and never to the wrong square.
static void seeds_growth_where_no_code_reaches(void **)
{
	Stereo st = stereo_scene(7);
	const Pattern &p = st.p;
	const std::vector<CameraModel> &cams = st.cams;
	Scene &s = st.s;
	const int cols = p.matrix.cols(), first_row = p.matrix.rows() - 3;
	int band = 0;
	for (size_t c = 0; c < s.dets.size(); c++) {
		std::vector<Square> &sq = s.dets[c].squares;
		auto in_band = [&](size_t i) { return s.cell_of[c][i] / cols >= first_row; };
		for (size_t i = 0; i < sq.size(); i++) {
			if (!in_band(i))
				continue;
			sq[i].cell = -1;
			band += c == 0;
			for (int &j : sq[i].neighbours)
				if (j >= 0 && !in_band(size_t(j))) {
					for (int &back : sq[size_t(j)].neighbours)
						if (back == int(i))
							back = -1;
					j = -1;
				}
		}
	}
	// Guided matching would reach this band from the squares beside it in the image (its depth
	// follows theirs here); off, so that only seeding can.
	MatchParams seeding, no_seed;
	seeding.guide.enabled = no_seed.guide.enabled = no_seed.seed.enabled = false;
	PairMatches without, with;
	assert_true(match_pair(s.dets[0], s.dets[1], cams[0], cams[1], p, no_seed, &without).ok());
	assert_true(match_pair(s.dets[0], s.dets[1], cams[0], cams[1], p, seeding, &with).ok());
	const Outcome ow = check(s, without), os = check(s, with);
	std::printf("band of %d squares without code or links: %d square matches without seeding, %d "
		    "with (%d seeds), %d wrong\n",
		    band, ow.centroids, os.centroids, with.seeded, os.wrong);
	assert_int_equal(without.seeded, 0);
	assert_true(with.seeded > 0);
	assert_int_equal(os.wrong, 0);
	assert_true(os.centroids >= ow.centroids + band / 2);

	// The same band with its letters unread has nothing to check a seed by: nothing is seeded.
	for (CameraDetections &d : s.dets)
		for (Square &q : d.squares)
			if (q.cell < 0)
				q.letter = -1;
	PairMatches blind;
	assert_true(match_pair(s.dets[0], s.dets[1], cams[0], cams[1], p, seeding, &blind).ok());
	assert_int_equal(blind.seeded, 0);
	assert_int_equal(check(s, blind).wrong, 0);
}

// A square cut or bent in a view (irregular) whose eight grid neighbours went undetected: guided
// matching still finds it, but with no matched point within a pitch nothing vouches for it — it
// would sit across an occluding contour (chin over neck) — and it is dropped; a regular square in
// its place is judged by the surface around it and kept.
static void isolated_irregular_square_is_dropped(void **)
{
	for (bool irregular : {false, true}) {
		Stereo st = stereo_scene(9);
		Scene &s = st.s;
		const int cols = st.p.matrix.cols(), centre = 7 * cols + 9;
		for (size_t c = 0; c < 2; c++) {
			std::vector<char> gone(s.dets[c].squares.size(), 0);
			for (size_t i = 0; i < gone.size(); i++) {
				const int dr = s.cell_of[c][i] / cols - centre / cols, dc = s.cell_of[c][i] % cols - centre % cols;
				if (s.copy_of[c][i] != 1 || std::abs(dr) > 1 || std::abs(dc) > 1)
					continue;
				if (dr || dc) {
					gone[i] = 1;
					continue;
				}
				Square &q = s.dets[c].squares[i];
				q.cell = -1; // no code: only guided matching can reach it
				q.irregular = irregular;
				q.has_corners = false;
			}
			remove_squares(&s, c, gone);
		}
		PairMatches pm;
		assert_true(match_pair(s.dets[0], s.dets[1], st.cams[0], st.cams[1], st.p, MatchParams{}, &pm).ok());
		int found = 0;
		for (const PointMatch &m : pm.matches)
			found += s.cell_of[0][size_t(m.square_a)] == centre && s.copy_of[0][size_t(m.square_a)] == 1;
		std::printf("%s square with no matched point within a pitch: %s (%d guided, %d pruned)\n",
			    irregular ? "irregular" : "regular", found ? "kept" : "dropped", pm.guided, pm.pruned);
		assert_true(pm.guided >= 1);
		assert_int_equal(found, irregular ? 0 : 1);
		assert_int_equal(check(s, pm).wrong, 0);
	}
}

// ---- the sub-stages one at a time (issue 11) --------------------------------------------------

// The square of camera c showing `cell` of slide copy `copy`, or -1.
static int square_of(const Scene &s, size_t c, int copy, int cell)
{
	for (size_t i = 0; i < s.cell_of[c].size(); i++)
		if (s.copy_of[c][i] == copy && s.cell_of[c][i] == cell)
			return int(i);
	return -1;
}

// The partner in camera b of square i of camera a, or -1.
static int partner_of(const PairMatches &pm, int i)
{
	for (const PointMatch &m : pm.matches)
		if (m.square_a == i)
			return m.square_b;
	return -1;
}

// Where camera b sees the point `mm` farther along camera a's ray through pa than the surface
// point that pa and pb show (their rays' midpoint): on pa's epipolar line, off the surface.
static cv::Point2d farther_in_b(const std::vector<CameraModel> &cams, const cv::Point2d &pa,
				const cv::Point2d &pb, double mm)
{
	std::vector<cv::Point2d> ua, ub;
	cv::undistortPoints(std::vector<cv::Point2d>{pa}, ua, cv::Mat(cams[0].K), cv::Mat(cams[0].dist));
	cv::undistortPoints(std::vector<cv::Point2d>{pb}, ub, cv::Mat(cams[1].K), cv::Mat(cams[1].dist));
	const cv::Matx33d R = cams[1].R * cams[0].R.t();
	const cv::Vec3d t = cams[1].T - R * cams[0].T;
	// Midpoint of the rays s·da and ob + u·db in camera a's frame (least squares in s, u).
	const cv::Vec3d da(ua[0].x, ua[0].y, 1), ob = -(R.t() * t), db = R.t() * cv::Vec3d(ub[0].x, ub[0].y, 1);
	const cv::Matx22d A(da.dot(da), -da.dot(db), -da.dot(db), db.dot(db));
	const cv::Vec2d su = A.solve(cv::Vec2d(da.dot(ob), -db.dot(ob)), cv::DECOMP_LU);
	cv::Vec3d xa = 0.5 * (su[0] * da + ob + su[1] * db);
	xa += mm * cv::normalize(xa);
	const cv::Vec3d world = cams[0].R.t() * (xa - cams[0].T);
	std::vector<cv::Point2d> px;
	cv::Mat rvec;
	cv::Rodrigues(cv::Mat(cams[1].R), rvec);
	cv::projectPoints(std::vector<cv::Point3d>{cv::Point3d(world)}, rvec, cv::Mat(cams[1].T), cv::Mat(cams[1].K),
			  cv::Mat(cams[1].dist), px);
	return px[0];
}

// Cuts square i of camera c out of the grid (its links both ways) and erases its code word:
// neither growing nor match_codes reaches it.
static void isolate(Scene *s, size_t c, size_t i)
{
	std::vector<Square> &sq = s->dets[c].squares;
	for (int &j : sq[i].neighbours)
		if (j >= 0) {
			for (int &back : sq[size_t(j)].neighbours)
				if (back == int(i))
					back = -1;
			j = -1;
		}
	sq[i].cell = -1;
}

static PairGeometry geometry_of(const Stereo &st, const Scene &s)
{
	PairGeometry g;
	assert_true(pair_geometry(s.dets[0], s.dets[1], st.cams[0], st.cams[1], &g).ok());
	assert_int_equal(g.na.size(), s.dets[0].squares.size() * kFeatureCount);
	return g;
}

// 4 (code): the grid-part agreement. A square of a wrong copy in b, moved onto the epipolar line
// of a square of camera a at a plausible depth (30 mm behind the face) where the right square
// went undetected, passes every test of its own; only its grid part, whose other shared cells are
// all off their lines, tells it is another copy. Refused; with the agreement off it is taken.
static void code_match_refuses_a_wrong_copy(void **)
{
	Stereo st = stereo_scene(13);
	Scene &s = st.s;
	const int cols = st.p.matrix.cols();
	int cell = -1, ia = -1, right = -1, wrong = -1;
	for (int r = 3; r + 3 < st.p.matrix.rows() && cell < 0; r++)
		for (int c = 3; c + 3 < cols && cell < 0; c++)
			for (int copy : {0, 2}) {
				ia = square_of(s, 0, 1, r * cols + c);
				right = square_of(s, 1, 1, r * cols + c);
				wrong = square_of(s, 1, copy, r * cols + c);
				if (ia >= 0 && right >= 0 && wrong >= 0) {
					cell = r * cols + c;
					break;
				}
			}
	assert_true(cell >= 0);
	Square &qw = s.dets[1].squares[size_t(wrong)];
	qw.centroid = farther_in_b(st.cams, s.dets[0].squares[size_t(ia)].centroid,
				   s.dets[1].squares[size_t(right)].centroid, 30);
	qw.has_corners = false;
	s.dets[1].squares[size_t(right)].cell = -1; // the right square's word unread
	const PairGeometry g = geometry_of(st, s);
	PairMatches pm, careless;
	assert_true(match_codes(s.dets[0], s.dets[1], g, st.p, PairCheckParams{}, CodeMatchParams{}, &pm).ok());
	CodeMatchParams no_agreement;
	no_agreement.min_part_agreement = 0;
	no_agreement.min_part_support = 0;
	assert_true(match_codes(s.dets[0], s.dets[1], g, st.p, PairCheckParams{}, no_agreement, &careless).ok());
	const Outcome o = check(s, pm), oc = check(s, careless);
	std::printf("code matching: %d square matches, %d wrong; the wrong copy's square on the line: "
		    "partner %d (agreement on), %d (off; it is square %d)\n",
		    o.centroids, o.wrong, partner_of(pm, ia), partner_of(careless, ia), wrong);
	assert_int_equal(partner_of(pm, ia), -1);
	assert_int_equal(o.wrong, 0);
	assert_true(o.centroids >= int(0.95 * o.possible) - 1);
	assert_int_equal(pm.grown + pm.guided + pm.seeded + pm.pruned, 0);
	assert_int_equal(partner_of(careless, ia), wrong);
	assert_int_equal(oc.wrong, 1);

	// Mismatched inputs are an error, not a guess.
	PairGeometry other = g;
	other.nb.pop_back();
	assert_false(match_codes(s.dets[0], s.dets[1], other, st.p, PairCheckParams{}, CodeMatchParams{}, &pm).ok());
}

// 4 (code): squares seen obliquely. The area centroid of a square is not the image of one surface
// point: on a pair converging by ~45 degrees a right match's centroids lie 2-6 px off their
// epipolar lines while its corners lie within 0.5 px (random booth 3803, pair 1-2). Every centroid
// of camera b moved 3 px across the rows, the corners left true: the squares are matched on their
// corners and their copy is told by the vote's wider tolerance; those without corners are not
// matched by their code. On centroids alone (corners off) nothing passes: the drift defeats it.
static void code_match_takes_oblique_squares_by_their_corners(void **)
{
	Stereo st = stereo_scene(17);
	Scene &s = st.s;
	std::vector<char> cornerless(s.dets[1].squares.size(), 0);
	for (size_t j = 0; j < s.dets[1].squares.size(); j++) {
		Square &q = s.dets[1].squares[j];
		q.centroid.y += 3;
		cornerless[j] = j % 5 == 0;
		q.has_corners = !cornerless[j];
	}
	const PairGeometry g = geometry_of(st, s);
	PairMatches pm, centroids_only;
	assert_true(match_codes(s.dets[0], s.dets[1], g, st.p, PairCheckParams{}, CodeMatchParams{}, &pm).ok());
	PairCheckParams no_corners;
	no_corners.corners = false;
	assert_true(match_codes(s.dets[0], s.dets[1], g, st.p, no_corners, CodeMatchParams{}, &centroids_only).ok());
	const Outcome o = check(s, pm), oc = check(s, centroids_only);
	int by_code_without_corners = 0;
	for (const PointMatch &m : pm.matches)
		by_code_without_corners += m.feature == kCentroid && cornerless[size_t(m.square_b)];
	std::printf("oblique squares: %d of %d possible matched on their corners (%d wrong, %d without "
		    "corners); on centroids alone %d\n",
		    o.centroids, o.possible, o.wrong, by_code_without_corners, oc.centroids);
	assert_int_equal(o.wrong, 0);
	assert_int_equal(by_code_without_corners, 0);
	assert_true(o.centroids >= int(0.75 * o.possible));
	assert_int_equal(o.corners, 4 * o.centroids);
	assert_int_equal(oc.centroids, 0);
}

// 4b: a square whose code word is unread in both views, between matched neighbours, is grown to
// its right partner; one whose letter contradicts its partner's is not.
static void grow_matches_a_square_without_code(void **)
{
	Stereo st = stereo_scene(15);
	Scene &s = st.s;
	const int cell = 7 * st.p.matrix.cols() + 9;
	const int ia = square_of(s, 0, 1, cell), ib = square_of(s, 1, 1, cell);
	assert_true(ia >= 0 && ib >= 0);
	s.dets[0].squares[size_t(ia)].cell = s.dets[1].squares[size_t(ib)].cell = -1;
	const PairGeometry g = geometry_of(st, s);
	PairMatches pm;
	assert_true(match_codes(s.dets[0], s.dets[1], g, st.p, PairCheckParams{}, CodeMatchParams{}, &pm).ok());
	assert_int_equal(partner_of(pm, ia), -1);
	const int by_code = check(s, pm).centroids;
	assert_true(grow_matches(s.dets[0], s.dets[1], g, PairCheckParams{}, GrowParams{}, &pm).ok());
	std::printf("grow: square without code %s (%d grown)\n", partner_of(pm, ia) == ib ? "matched" : "missed",
		    pm.grown);
	assert_int_equal(partner_of(pm, ia), ib);
	assert_int_equal(pm.grown, 1);
	assert_int_equal(check(s, pm).centroids, by_code + 1);
	assert_int_equal(check(s, pm).wrong, 0);
	const PointMatch &m = *std::find_if(pm.matches.begin(), pm.matches.end(),
					    [&](const PointMatch &x) { return x.square_a == ia; });
	assert_true(m.grown);
	assert_int_equal(m.cell, -1);

	// Its letter read differently in b: a different square, never grown to.
	Square &qb = s.dets[1].squares[size_t(ib)];
	qb.letter = (qb.letter + 1) % st.p.matrix.letters();
	PairMatches contra;
	assert_true(match_codes(s.dets[0], s.dets[1], g, st.p, PairCheckParams{}, CodeMatchParams{}, &contra).ok());
	assert_true(grow_matches(s.dets[0], s.dets[1], g, PairCheckParams{}, GrowParams{}, &contra).ok());
	assert_int_equal(partner_of(contra, ia), -1);
	assert_int_equal(contra.grown, 0);

	// Disabled, it adds nothing.
	PairMatches off;
	GrowParams no_growth;
	no_growth.enabled = false;
	qb.letter = (qb.letter + st.p.matrix.letters() - 1) % st.p.matrix.letters();
	assert_true(match_codes(s.dets[0], s.dets[1], g, st.p, PairCheckParams{}, CodeMatchParams{}, &off).ok());
	assert_true(grow_matches(s.dets[0], s.dets[1], g, PairCheckParams{}, no_growth, &off).ok());
	assert_int_equal(off.grown, 0);
}

// 4c: a square cut out of both grids and without a code word (neither code nor growth reach it)
// is matched when its partner lies on its epipolar line within its matched neighbours' depth
// range; moved 30 mm behind the face along that line (depth range ± 8 mm) it is not.
static void guide_matches_within_the_neighbours_depth(void **)
{
	for (double behind_mm : {0.0, 30.0}) {
		Stereo st = stereo_scene(17);
		Scene &s = st.s;
		const int cell = 7 * st.p.matrix.cols() + 9;
		const int ia = square_of(s, 0, 1, cell), ib = square_of(s, 1, 1, cell);
		assert_true(ia >= 0 && ib >= 0);
		isolate(&s, 0, size_t(ia));
		isolate(&s, 1, size_t(ib));
		Square &qb = s.dets[1].squares[size_t(ib)];
		if (behind_mm > 0) {
			qb.centroid = farther_in_b(st.cams, s.dets[0].squares[size_t(ia)].centroid, qb.centroid, behind_mm);
			qb.has_corners = false;
		}
		const PairGeometry g = geometry_of(st, s);
		PairMatches pm;
		assert_true(match_codes(s.dets[0], s.dets[1], g, st.p, PairCheckParams{}, CodeMatchParams{}, &pm).ok());
		assert_true(grow_matches(s.dets[0], s.dets[1], g, PairCheckParams{}, GrowParams{}, &pm).ok());
		assert_int_equal(partner_of(pm, ia), -1);
		assert_true(guide_matches(s.dets[0], s.dets[1], g, PairCheckParams{}, GuideParams{}, &pm).ok());
		std::printf("guide: partner %.0f mm behind the face: %s (%d guided)\n", behind_mm,
			    partner_of(pm, ia) == ib ? "matched" : "not matched", pm.guided);
		assert_int_equal(partner_of(pm, ia), behind_mm > 0 ? -1 : ib);
		assert_int_equal(pm.guided, behind_mm > 0 ? 0 : 1);
		assert_int_equal(check(s, pm).wrong, 0);
	}
}

// 4d: an island of 3 × 3 squares cut out of both grids, without code words (nothing else reaches
// it), is entered from the one candidate pair whose trial growth pairs agreeing letters, and
// grown through; with its letters unread there is nothing to check a seed by.
static void seed_matches_enter_an_island(void **)
{
	for (bool letters : {true, false}) {
		Stereo st = stereo_scene(19);
		Scene &s = st.s;
		const int cols = st.p.matrix.cols(), centre = 7 * cols + 9;
		std::vector<std::pair<int, int>> island; // (square in a, its partner in b)
		for (size_t c = 0; c < 2; c++) {
			std::vector<Square> &sq = s.dets[c].squares;
			auto inside = [&](size_t i) {
				const int dr = s.cell_of[c][i] / cols - centre / cols, dc = s.cell_of[c][i] % cols - centre % cols;
				return s.copy_of[c][i] == 1 && std::abs(dr) <= 1 && std::abs(dc) <= 1;
			};
			for (size_t i = 0; i < sq.size(); i++) {
				if (!inside(i))
					continue;
				sq[i].cell = -1;
				sq[i].letter = letters ? sq[i].letter : -1;
				for (int &j : sq[i].neighbours)
					if (j >= 0 && !inside(size_t(j))) {
						for (int &back : sq[size_t(j)].neighbours)
							if (back == int(i))
								back = -1;
						j = -1;
					}
				if (c == 0)
					island.emplace_back(int(i), square_of(s, 1, 1, s.cell_of[0][i]));
			}
		}
		assert_int_equal(island.size(), 9);
		const PairGeometry g = geometry_of(st, s);
		PairMatches pm;
		assert_true(match_codes(s.dets[0], s.dets[1], g, st.p, PairCheckParams{}, CodeMatchParams{}, &pm).ok());
		assert_true(grow_matches(s.dets[0], s.dets[1], g, PairCheckParams{}, GrowParams{}, &pm).ok());
		for (const auto &[ia, ib] : island) {
			assert_true(ib >= 0);
			assert_int_equal(partner_of(pm, ia), -1);
		}
		const int grown = pm.grown;
		assert_true(seed_matches(s.dets[0], s.dets[1], g, PairCheckParams{}, SeedParams{}, &pm).ok());
		int found = 0;
		for (const auto &[ia, ib] : island)
			found += partner_of(pm, ia) == ib;
		std::printf("seed: island of 9 squares without code or links, letters %s: %d matched (%d seeded, "
			    "%d grown from them)\n",
			    letters ? "read" : "unread", found, pm.seeded, pm.grown - grown);
		assert_int_equal(found, letters ? 9 : 0);
		assert_int_equal(pm.seeded, letters ? 1 : 0);
		assert_int_equal(pm.grown - grown, letters ? 8 : 0);
		assert_int_equal(check(s, pm).wrong, 0);
	}
}

// 4e: a square matched by its centroid alone (no corners to check it by), its partner in b moved
// along the epipolar line so that the pair lies 4 mm behind the face (more than the 2.5 mm
// limit): pruned; 1 mm behind: kept. Nothing else is touched (every other match has corners).
static void prune_matches_off_the_surface(void **)
{
	for (double behind_mm : {1.0, 4.0}) {
		Stereo st = stereo_scene(21);
		Scene &s = st.s;
		const int cell = 7 * st.p.matrix.cols() + 9;
		const int ia = square_of(s, 0, 1, cell), ib = square_of(s, 1, 1, cell);
		assert_true(ia >= 0 && ib >= 0);
		Square &qa = s.dets[0].squares[size_t(ia)], &qb = s.dets[1].squares[size_t(ib)];
		qb.centroid = farther_in_b(st.cams, qa.centroid, qb.centroid, behind_mm);
		qa.has_corners = qb.has_corners = false;
		const PairGeometry g = geometry_of(st, s);
		PairMatches pm;
		assert_true(match_codes(s.dets[0], s.dets[1], g, st.p, PairCheckParams{}, CodeMatchParams{}, &pm).ok());
		assert_int_equal(partner_of(pm, ia), ib);
		const size_t before = pm.matches.size();
		assert_true(prune_matches(s.dets[0], s.dets[1], g, PruneParams{}, &pm).ok());
		const bool pruned = behind_mm > 2.5;
		std::printf("prune: centroid-only match %.0f mm behind the face: %s (%d pruned)\n", behind_mm,
			    partner_of(pm, ia) == ib ? "kept" : "pruned", pm.pruned);
		assert_int_equal(partner_of(pm, ia), pruned ? -1 : ib);
		assert_int_equal(pm.pruned, pruned ? 1 : 0);
		assert_int_equal(pm.matches.size(), before - (pruned ? 1 : 0));
	}
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(matches_pair_the_same_copy_only),
		cmocka_unit_test(grows_to_squares_without_code),
		cmocka_unit_test(seeds_growth_where_no_code_reaches),
		cmocka_unit_test(isolated_irregular_square_is_dropped),
		cmocka_unit_test(code_match_refuses_a_wrong_copy),
		cmocka_unit_test(code_match_takes_oblique_squares_by_their_corners),
		cmocka_unit_test(grow_matches_a_square_without_code),
		cmocka_unit_test(guide_matches_within_the_neighbours_depth),
		cmocka_unit_test(seed_matches_enter_an_island),
		cmocka_unit_test(prune_matches_off_the_surface),
	};
	return cmocka_run_group_tests(tests, nullptr, nullptr);
}
