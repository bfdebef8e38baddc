// The procedural head: an implicit surface (smooth unions of ellipsoids, cones and capsules
// placed by adult anthropometry) polygonised by surface nets, vertices projected back onto
// the surface, normals from the field's gradient, albedo painted from the 3-D position.
#include "sim/internal.hpp"

#include <opencv2/core/utility.hpp>

#include <algorithm>
#include <cmath>

namespace facescan::sim {

namespace {

using V3 = cv::Vec3f;

inline float len(const V3 &v)
{
	return std::sqrt(v.dot(v));
}

// Smooth minimum (polynomial, blend width k) and its subtraction counterpart.
inline float smin(float a, float b, float k)
{
	float h = std::max(k - std::fabs(a - b), 0.f) / k;
	return std::min(a, b) - h * h * k * 0.25f;
}
inline float ssub(float a, float b, float k) // a minus b
{
	return -smin(-a, b, k);
}

// Approximate signed distance to an axis-aligned ellipsoid (Quilez's bound).
inline float ellipsoid(const V3 &p, const V3 &c, const V3 &r)
{
	V3 q = p - c;
	V3 a(q[0] / r[0], q[1] / r[1], q[2] / r[2]);
	V3 b(q[0] / (r[0] * r[0]), q[1] / (r[1] * r[1]), q[2] / (r[2] * r[2]));
	float k0 = len(a), k1 = len(b);
	if (k1 < 1e-9f)
		return -std::min(r[0], std::min(r[1], r[2]));
	return k0 * (k0 - 1.f) / k1;
}

// Round cone: spheres of radius ra at a and rb at b joined by their tangent cone.
inline float round_cone(const V3 &p, const V3 &a, const V3 &b, float ra, float rb)
{
	V3 ba = b - a, pa = p - a;
	float l2 = ba.dot(ba);
	float t = std::clamp(pa.dot(ba) / l2, 0.f, 1.f);
	V3 q = pa - ba * t;
	return len(q) - (ra + (rb - ra) * t);
}

inline float capsule(const V3 &p, const V3 &a, const V3 &b, float r)
{
	return round_cone(p, a, b, r, r);
}

// p rotated about +y by -angle around centre c, for shapes tilted by `angle`.
inline V3 rot_y(const V3 &p, const V3 &c, float cs, float sn)
{
	V3 q = p - c;
	return c + V3(cs * q[0] - sn * q[2], q[1], sn * q[0] + cs * q[2]);
}

// HeadShape as the field uses it: the inverse of the whole-head scale, the left/right
// asymmetry, and the feature parameters in float.
struct Shape {
	V3 inv_scale{1, 1, 1};
	float asym = 0, lipschitz = 1;
	float nose_len = 1, nose_w = 1, nose_proj = 1, nose_dev = 0;
	float chin = 1, cheeks = 1, lips = 1, sockets = 1, ear_up = 0, ear_back = 0;
	bool shoulders = false;
};

Shape make_shape(const HeadShape &h)
{
	Shape s;
	s.inv_scale = V3(float(1 / h.width), float(1 / h.height), float(1 / h.depth));
	s.asym = float(h.asymmetry);
	// The field is evaluated at warped coordinates: dividing by this keeps it a distance bound
	// (the warp stretches by at most 1 + 1.5 |asym| after the scale).
	s.lipschitz = (1 + 1.5f * std::fabs(s.asym)) * std::max(s.inv_scale[0], std::max(s.inv_scale[1], s.inv_scale[2]));
	s.nose_len = float(h.nose_length);
	s.nose_w = float(h.nose_width);
	s.nose_proj = float(h.nose_projection);
	s.nose_dev = float(h.nose_deviation_mm);
	s.chin = float(h.chin);
	s.cheeks = float(h.cheeks);
	s.lips = float(h.lips);
	s.sockets = float(h.eye_sockets);
	s.ear_up = float(h.ear_up_mm);
	s.ear_back = float(h.ear_back_mm);
	return s;
}

// World (head) coordinates to the canonical head's: undo the scale, then widen the subject's
// left (+x) and narrow the right by `asym` (smoothly across the midline).
inline V3 canonical(const V3 &p, const Shape &s)
{
	V3 q(p[0] * s.inv_scale[0], p[1] * s.inv_scale[1], p[2] * s.inv_scale[2]);
	q[0] *= 1.f - s.asym * std::tanh(q[0] / 30.f);
	return q;
}

// The head's field in canonical coordinates: negative inside. Both sides are built from the
// same half by mirroring x.
float canonical_field(const V3 &p0, const Shape &s)
{
	V3 p(std::fabs(p0[0]), p0[1], p0[2]); // symmetric parts use |x|
	// Cranium and face.
	float d = ellipsoid(p0, V3(0, 22, -10), V3(75, 98, 97));
	d = smin(d, ellipsoid(p0, V3(0, -35, 22), V3(60, 72, 70)), 24);
	// Lower jaw towards the gonion, and the chin.
	d = smin(d, capsule(p, V3(42, -74, 0), V3(14, -98, 60), 13), 22);
	d = smin(d, ellipsoid(p0, V3(0, -98, 72 + 10 * (s.chin - 1)), V3(22, 14, 16) * s.chin), 16);
	// Neck, cut flat at the bottom; or continuing into shoulders and an upper chest (trapezius
	// slopes, deltoids), cut flat lower down.
	d = smin(d, capsule(p0, V3(0, -70, -22), V3(0, -230, -32), 54), 24);
	if (!s.shoulders) {
		d = std::max(d, -(p0[1] + 205.f));
	} else {
		float torso = ellipsoid(p0, V3(0, -300, -30), V3(165, 70, 95));
		torso = smin(torso, capsule(p, V3(40, -245, -30), V3(150, -285, -30), 34), 30);
		torso = smin(torso, ellipsoid(p, V3(150, -300, -28), V3(40, 45, 48)), 20);
		d = smin(d, torso, 45);
		d = std::max(d, -(p0[1] + 330.f));
	}
	// Forehead fullness and brow ridge.
	d = smin(d, ellipsoid(p0, V3(0, 45, 52), V3(62, 42, 36)), 18);
	d = smin(d, ellipsoid(p, V3(26, 13, 80), V3(24, 8, 10)), 10);
	// Cheekbones and cheeks.
	d = smin(d, ellipsoid(p, V3(48, -8, 56), V3(16, 10, 15)), 18);
	d = smin(d, ellipsoid(p, V3(36, -30, 60), V3(22, 24, 20) * s.cheeks), 24);
	// Eye sockets, then the eyes in them.
	d = ssub(d, ellipsoid(p, V3(32, 3, 90), V3(19, 11, 16 * s.sockets)), 7);
	d = smin(d, ellipsoid(p, V3(32, 1, 70), V3(12, 12, 12)), 1.5f);
	// Nose: bridge to tip, alae, nostrils.
	const float tip_y = 8 - 38 * s.nose_len, proj = 26 * s.nose_proj;
	d = smin(d, round_cone(p0, V3(0, 8, 85), V3(s.nose_dev, tip_y, 85 + proj), 6.f * s.nose_w, 8.5f * s.nose_w), 7);
	d = smin(d, ellipsoid(p, V3(11 * s.nose_w, tip_y - 7, 85 + proj * (11.f / 26)), V3(8 * s.nose_w, 7, 9)), 8);
	d = ssub(d, ellipsoid(p, V3(7 * s.nose_w, tip_y - 14, 85 + proj * (14.f / 26)), V3(4 * s.nose_w, 2.5f, 5.5f)), 2);
	// Lips and the mouth line.
	d = smin(d, ellipsoid(p0, V3(0, -59, 86), V3(24, 7 * s.lips, 9 * s.lips)), 8);
	d = smin(d, ellipsoid(p0, V3(0, -72, 84), V3(21, 7 * s.lips, 9 * s.lips)), 8);
	d = ssub(d, ellipsoid(p0, V3(0, -65.5f, 95), V3(24, 1.2f, 9)), 2);
	// Ears: a tilted disc flaring out behind the jaw, with the concha hollowed out.
	const float cs = std::cos(0.35f), sn = std::sin(0.35f);
	const V3 ear_c(76, -12 + s.ear_up, -14 - s.ear_back);
	V3 e = rot_y(p, ear_c, cs, sn);
	float ear = ellipsoid(e, ear_c, V3(6, 31, 18));
	ear = ssub(ear, ellipsoid(e, ear_c + V3(6, -4, 3), V3(5, 13, 9)), 3);
	d = smin(d, ear, 5);
	return d;
}

float head_field(const V3 &p, const Shape &s)
{
	return canonical_field(canonical(p, s), s) / s.lipschitz;
}

V3 field_gradient(const V3 &p, const Shape &s)
{
	const float h = 0.05f;
	V3 g(head_field(p + V3(h, 0, 0), s) - head_field(p - V3(h, 0, 0), s),
	     head_field(p + V3(0, h, 0), s) - head_field(p - V3(0, h, 0), s),
	     head_field(p + V3(0, 0, h), s) - head_field(p - V3(0, 0, h), s));
	return g * (0.5f / h);
}

inline float smoothstep(float e0, float e1, float x)
{
	float t = std::clamp((x - e0) / (e1 - e0), 0.f, 1.f);
	return t * t * (3 - 2 * t);
}

// Value noise on a 3-D lattice (trilinear, smooth-stepped), 0..1, for skin blotches.
float value_noise(const V3 &p, float scale, uint64_t key)
{
	V3 q = p * (1.f / scale);
	float fx = std::floor(q[0]), fy = std::floor(q[1]), fz = std::floor(q[2]);
	float tx = q[0] - fx, ty = q[1] - fy, tz = q[2] - fz;
	tx = tx * tx * (3 - 2 * tx);
	ty = ty * ty * (3 - 2 * ty);
	tz = tz * tz * (3 - 2 * tz);
	auto at = [&](int dx, int dy, int dz) {
		uint64_t h = uint64_t(int64_t(fx) + dx) * 73856093ULL ^
			     uint64_t(int64_t(fy) + dy) * 19349663ULL ^
			     uint64_t(int64_t(fz) + dz) * 83492791ULL;
		return float(internal::uniform01(key, h));
	};
	float c00 = at(0, 0, 0) * (1 - tx) + at(1, 0, 0) * tx;
	float c10 = at(0, 1, 0) * (1 - tx) + at(1, 1, 0) * tx;
	float c01 = at(0, 0, 1) * (1 - tx) + at(1, 0, 1) * tx;
	float c11 = at(0, 1, 1) * (1 - tx) + at(1, 1, 1) * tx;
	float c0 = c00 * (1 - ty) + c10 * ty, c1 = c01 * (1 - ty) + c11 * ty;
	return c0 * (1 - tz) + c1 * tz;
}

V3 mix(const V3 &a, const V3 &b, float t)
{
	return a * (1 - t) + b * t;
}

// Height of the scalp hair's edge (canonical coordinates) at azimuth `az` about +y (0 in front,
// pi at the back): it falls from the forehead past the temples to the nape.
float hairline(float az)
{
	float line = az < 0.9f ? 62 - 25 * az : (az < 1.75f ? 40 - 26 * (az - 0.9f) / 0.85f : 14 - 60 * (az - 1.75f));
	return std::max(line, -75.f);
}

// Linear albedo at a point of the head (canonical coordinates). Every HeadLook term is written
// so that its default leaves the canonical head's albedo bit-identical.
V3 head_albedo(const V3 &p0, const V3 &skin, uint64_t key, const Shape &s, const HeadLook &look)
{
	V3 p(std::fabs(p0[0]), p0[1], p0[2]);
	// Skin: blotches at two scales, redder cheeks and nose tip, slightly darker neck.
	float n = 0.6f * value_noise(p0, 14, key) + 0.4f * value_noise(p0, 4, key + 1);
	float blotch = 0.92f + 0.16f * n;
	if (look.blotches != 1)
		blotch = 1 + float(look.blotches) * (blotch - 1);
	V3 c = skin * blotch;
	if (look.freckles > 0) {
		// Freckles: small dark spots (a 2.2 mm noise above a threshold) on the nose, cheeks and
		// forehead, slightly more brown than dark.
		float zone = smoothstep(45, 70, p[2]) * smoothstep(-55, -35, p[1]) * smoothstep(75, 55, p[1]);
		float thr = 1 - 0.16f * float(look.freckles);
		float fr = smoothstep(thr, thr + 0.04f, value_noise(p0, 2.2f, key + 5)) * zone;
		float k = float(look.freckle_darkness) * fr;
		c = V3(c[0] * (1 - 0.8f * k), c[1] * (1 - k), c[2] * (1 - 1.15f * k));
	}
	float cheek = std::exp(-((p[0] - 40) * (p[0] - 40) + (p[1] + 28) * (p[1] + 28)) / 500.f) *
		      smoothstep(30, 60, p[2]);
	float nose = std::exp(-(p[0] * p[0] + (p[1] + 33) * (p[1] + 33)) / 120.f) * smoothstep(95, 105, p[2]);
	float red = std::min(1.f, 0.5f * cheek + 0.4f * nose);
	if (look.redness != 1)
		red = std::min(1.f, red * float(look.redness));
	c = V3(c[0] * (1 + 0.06f * red), c[1] * (1 - 0.10f * red), c[2] * (1 - 0.08f * red));
	c *= 1.f - 0.08f * smoothstep(-100, -140, p[1]);
	// Lips: redder and darker, fading out at the vermilion border.
	float lip = smoothstep(1.f, 0.7f,
			       std::sqrt(p[0] * p[0] / (24.f * 24.f) + (p[1] + 65.5f) * (p[1] + 65.5f) / (13.f * 13.f))) *
		    smoothstep(78, 86, p[2]);
	if (look.lip_red == 1 && look.lip_darkness == 1) {
		c = mix(c, V3(skin[0] * 0.78f, skin[1] * 0.45f, skin[2] * 0.50f), lip);
	} else {
		const float L = float(look.lip_red), D = float(look.lip_darkness);
		c = mix(c, V3(skin[0] * (1 - 0.22f * L), skin[1] * (1 - 0.55f * L), skin[2] * (1 - 0.50f * L)) * D, lip);
	}
	// Eyes: sclera, iris, pupil on the eyeball's front.
	V3 eye_c(32, 1, 70);
	V3 q = p - eye_c;
	if (std::fabs(len(q) - 12) < 1.2f && q[2] > 0) {
		float r = std::sqrt(q[0] * q[0] + q[1] * q[1]);
		V3 sclera(0.70f, 0.66f, 0.62f), iris(0.16f, 0.10f, 0.05f), pupil(0.015f, 0.015f, 0.015f);
		V3 e = mix(sclera, iris, smoothstep(6.2f, 5.6f, r));
		c = mix(e, pupil, smoothstep(2.6f, 2.1f, r));
	}
	// Brows: an arc of hair over each socket, with strands from the noise.
	float bx = (p[0] - 31) / 20.f, by = p[1] - (17 - 4 * bx * bx);
	float brow = smoothstep(1.05f, 0.85f, std::fabs(bx)) * smoothstep(4.5f, 2.5f, std::fabs(by) / float(look.brow_width)) *
		     smoothstep(70, 80, p[2]);
	brow *= 0.6f + 0.4f * value_noise(p0, 1.2f, key + 2);
	const V3 hair = look.hair;
	c = mix(c, hair, brow * float(look.brow_darkness));
	if (look.stubble > 0) {
		// Beard shadow: follicle dots (0.7 mm noise) over the upper lip, chin and jaw down the
		// neck's front, off the lips.
		float upper_lip = smoothstep(-47, -52, p[1]) * smoothstep(-64, -60, p[1]) * smoothstep(26, 18, p[0]);
		float jaw = smoothstep(-68, -80, p[1]) * smoothstep(-150, -125, p[1]) * smoothstep(-20, 10, p[2]);
		float zone = std::max(upper_lip, jaw) * (1 - lip);
		float dots = smoothstep(0.45f, 0.65f, value_noise(p0, 0.7f, key + 7));
		c = mix(c, hair, std::min(1.f, float(look.stubble) * (0.35f + 0.45f * dots)) * zone);
	}
	// Scalp hair above a hairline that falls from the forehead to the nape.
	float az = std::atan2(p[0], p[2]); // 0 in front, pi at the back
	float line = hairline(az) + float(look.hairline_mm);
	const float ey = p[1] - s.ear_up, ez = p[2] + s.ear_back;
	bool ear_zone = p[0] > 66 && ey < 22 && ey > -48 && ez < 10 && ez > -38;
	float h = smoothstep(line - 3, line + 3, p[1]) * (ear_zone ? 0.f : 1.f);
	h *= 0.85f + 0.15f * value_noise(p0, 2, key + 3);
	if (look.hair_fringe > 0 && !ear_zone) {
		// Wisps reaching below the hairline: strands from a fine noise, thinning downwards.
		float reach = 14 * float(look.hair_fringe);
		float band = smoothstep(line - 3 - reach, line - 3, p[1]);
		float strands = smoothstep(0.55f, 0.7f, value_noise(V3(p0[0] * 2, p0[1] * 0.4f, p0[2] * 2), 1.0f, key + 6));
		h = std::max(h, band * strands * 0.9f);
	}
	c = mix(c, hair * (0.8f + 0.5f * value_noise(p0, 6, key + 4)), h);
	if (s.shoulders) // the shoulders' skin a little less sunned than the face
		c *= 1.f - 0.06f * smoothstep(-215, -250, p[1]);
	for (int k = 0; k < 3; k++)
		c[k] = std::clamp(c[k], 0.005f, 0.95f);
	return c;
}

// Moves surface-net vertices onto the zero set of `field` (Newton steps no longer than a cell,
// so a vertex stays near its cell) and gives each the normalised `gradient` there.
template <class Field, class Gradient>
void settle(Mesh *mesh, float h, const Field &field, const Gradient &gradient)
{
	Mesh &m = *mesh;
	m.normals.resize(m.vertices.size());
	cv::parallel_for_(cv::Range(0, int(m.vertices.size())), [&](const cv::Range &r) {
		for (int vi = r.start; vi < r.end; vi++) {
			V3 p = m.vertices[size_t(vi)];
			for (int it = 0; it < 4; it++) {
				V3 g = gradient(p);
				float g2 = g.dot(g);
				if (g2 < 1e-8f)
					break;
				V3 step = g * (field(p) / g2);
				if (len(step) > h)
					step *= h / len(step);
				p -= step;
			}
			V3 g = gradient(p);
			float gl = len(g);
			m.vertices[size_t(vi)] = p;
			m.normals[size_t(vi)] = gl > 1e-8f ? g * (1.f / gl) : V3(0, 0, 1);
		}
	});
}

// Albedo painted from each vertex's position in canonical coordinates.
void paint(const HeadSpec &spec, const Shape &shape, const V3 &skin, Mesh *mesh)
{
	const uint64_t key = internal::mix64(spec.seed ^ 0x5ea1f00dULL);
	mesh->colors.resize(mesh->vertices.size());
	cv::parallel_for_(cv::Range(0, int(mesh->vertices.size())), [&](const cv::Range &r) {
		for (int vi = r.start; vi < r.end; vi++)
			mesh->colors[size_t(vi)] =
				head_albedo(canonical(mesh->vertices[size_t(vi)], shape), skin, key, shape, spec.look);
	});
}

// The scanned head (spec.scan_dir): the skin iso-surface of its volume by the same surface
// nets, the largest connected piece only (a CT's head rest and table are separate pieces),
// painted as a canonical-shaped head with spec's look.
Status make_scan_head(const HeadSpec &spec, const V3 &skin, Mesh *ret_mesh)
{
	internal::ScanVolume vol;
	Status st = internal::load_scan_volume(spec.scan_dir, &vol);
	if (!st.ok())
		return st;
	const float h = float(spec.cell_mm);
	const V3 lo = vol.lo - V3(2 * h, 2 * h, 2 * h);
	const int nx = int(std::ceil((vol.hi[0] - lo[0]) / h)) + 3;
	const int ny = int(std::ceil((vol.hi[1] - lo[1]) / h)) + 3;
	const int nz = int(std::ceil((vol.hi[2] - lo[2]) / h)) + 3;
	std::vector<float> f(size_t(nx) * size_t(ny) * size_t(nz));
	cv::parallel_for_(cv::Range(0, nz), [&](const cv::Range &r) {
		for (int k = r.start; k < r.end; k++)
			for (int j = 0; j < ny; j++)
				for (int i = 0; i < nx; i++)
					f[(size_t(k) * size_t(ny) + size_t(j)) * size_t(nx) + size_t(i)] =
						internal::scan_field(vol, lo + V3(float(i) * h, float(j) * h, float(k) * h));
	});
	Mesh m;
	internal::surface_nets(f, nx, ny, nz, lo, h, &m);
	f.clear();
	f.shrink_to_fit();
	internal::keep_largest_piece(&m);
	if (m.vertices.empty())
		return Status::error(-EINVAL, "scan head in " + spec.scan_dir + ": no skin surface in the volume");
	auto field = [&](const V3 &p) { return internal::scan_field(vol, p); };
	settle(&m, h, field, [&](const V3 &p) {
		const float d = 0.25f;
		V3 g(field(p + V3(d, 0, 0)) - field(p - V3(d, 0, 0)), field(p + V3(0, d, 0)) - field(p - V3(0, d, 0)),
		     field(p + V3(0, 0, d)) - field(p - V3(0, 0, d)));
		return g * (0.5f / d);
	});
	paint(spec, Shape(), skin, &m);
	internal::orient_outwards(&m);
	*ret_mesh = std::move(m);
	return Status();
}

} // namespace

const std::vector<HeadShapeRange> &head_shape_ranges()
{
	static const std::vector<HeadShapeRange> ranges = {
		{"width", &HeadShape::width, 0.92, 1.08},
		{"height", &HeadShape::height, 0.92, 1.08},
		{"depth", &HeadShape::depth, 0.92, 1.08},
		{"nose_length", &HeadShape::nose_length, 0.87, 1.15},
		{"nose_width", &HeadShape::nose_width, 0.87, 1.15},
		{"nose_projection", &HeadShape::nose_projection, 0.87, 1.15},
		{"chin", &HeadShape::chin, 0.87, 1.15},
		{"cheeks", &HeadShape::cheeks, 0.85, 1.15},
		{"lips", &HeadShape::lips, 0.85, 1.15},
		{"eye_sockets", &HeadShape::eye_sockets, 0.85, 1.15},
		{"ear_up_mm", &HeadShape::ear_up_mm, -4, 4},
		{"ear_back_mm", &HeadShape::ear_back_mm, -4, 4},
		{"asymmetry", &HeadShape::asymmetry, -0.025, 0.025},
		{"nose_deviation_mm", &HeadShape::nose_deviation_mm, -2.5, 2.5},
	};
	return ranges;
}

std::vector<char> face_region(const HeadSpec &spec, const Mesh &head)
{
	Shape shape = make_shape(spec.shape);
	shape.shoulders = spec.look.shoulders;
	std::vector<char> out(head.vertices.size(), 0);
	for (size_t i = 0; i < head.vertices.size(); i++) {
		const V3 q = canonical(head.vertices[i], shape);
		const float az = std::atan2(std::fabs(q[0]), q[2]);
		const float ny = head.normals.empty() ? 0.f : head.normals[i][1];
		// In front of the ears (the tragus is at ~1.6 rad), below the hairline, above the
		// chin's lowest point, and not the jaw's or chin's under-side.
		out[i] = az < 1.55f && q[1] <= hairline(az) + float(spec.look.hairline_mm) && q[1] >= -118.f && ny > -0.5f;
	}
	return out;
}

const std::vector<HeadLookRange> &head_look_ranges()
{
	static const std::vector<HeadLookRange> ranges = {
		{"blotches", &HeadLook::blotches, 0.5, 2.5},
		{"freckles", &HeadLook::freckles, 0, 1},
		{"freckle_darkness", &HeadLook::freckle_darkness, 0.15, 0.5},
		{"redness", &HeadLook::redness, 0.3, 2},
		{"brow_darkness", &HeadLook::brow_darkness, 0.3, 1},
		{"brow_width", &HeadLook::brow_width, 0.7, 1.5},
		{"lip_red", &HeadLook::lip_red, 0.3, 1.5},
		{"lip_darkness", &HeadLook::lip_darkness, 0.6, 1.1},
		{"stubble", &HeadLook::stubble, 0, 1},
		{"hairline_mm", &HeadLook::hairline_mm, -15, 20},
		{"hair_fringe", &HeadLook::hair_fringe, 0, 1},
	};
	return ranges;
}

HeadAppearance random_head_appearance(uint64_t head_seed)
{
	HeadAppearance a;
	const uint64_t key = internal::mix64(head_seed ^ 0x100cbeefULL);
	uint64_t i = 0;
	// Skin tone: along a light-to-dark line of linear albedos (fair to deep brown), the
	// canonical (0.62, 0.43, 0.34) near its light end and the "dark" scene near 0.75.
	const double t = internal::uniform01(key, i++);
	const cv::Vec3d light(0.70, 0.50, 0.41), dark(0.12, 0.065, 0.042);
	// Interpolated in log albedo: perceptually even steps between the ends.
	for (int k = 0; k < 3; k++)
		a.skin[k] = float(std::exp((1 - t) * std::log(light[k]) + t * std::log(dark[k])));
	a.skin_tone = t;
	for (const HeadLookRange &r : head_look_ranges())
		a.look.*r.member = r.lo + (r.hi - r.lo) * internal::uniform01(key, i++);
	// Freckles are mostly a light-skin trait; stubble on about half the heads.
	a.look.freckles *= std::max(0.0, 1 - 1.5 * t);
	if (internal::uniform01(key, i++) < 0.5)
		a.look.stubble = 0;
	// Hair: black, dark brown, brown, blond, red or grey.
	static const cv::Vec3f hairs[6] = {{0.02f, 0.018f, 0.016f}, {0.045f, 0.032f, 0.024f}, {0.10f, 0.065f, 0.04f},
					   {0.32f, 0.24f, 0.13f},   {0.22f, 0.08f, 0.03f},    {0.30f, 0.29f, 0.28f}};
	a.look.hair = hairs[std::min(5, int(internal::uniform01(key, i++) * 6))];
	a.look.shoulders = internal::uniform01(key, i++) < 0.75;
	return a;
}

HeadShape random_head_shape(uint64_t head_seed)
{
	HeadShape h;
	const uint64_t key = internal::mix64(head_seed ^ 0x4eadc0deULL);
	uint64_t i = 0;
	for (const HeadShapeRange &r : head_shape_ranges())
		h.*r.member = r.lo + (r.hi - r.lo) * internal::uniform01(key, i++);
	return h;
}

void internal::surface_nets(const std::vector<float> &f, int nx, int ny, int nz, const cv::Vec3f &lo, float h,
			    Mesh *ret_mesh)
{
	auto idx = [&](int i, int j, int k) { return (size_t(k) * size_t(ny) + size_t(j)) * size_t(nx) + size_t(i); };
	auto point = [&](int i, int j, int k) { return lo + V3(float(i) * h, float(j) * h, float(k) * h); };
	// One vertex per cell with a sign change, at the mean of its edge crossings.
	Mesh m;
	std::vector<int> cell_vertex(size_t(nx) * size_t(ny) * size_t(nz), -1);
	static const int corner[8][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0},
					 {0, 0, 1}, {1, 0, 1}, {0, 1, 1}, {1, 1, 1}};
	static const int edge[12][2] = {{0, 1}, {2, 3}, {4, 5}, {6, 7}, {0, 2}, {1, 3},
					{4, 6}, {5, 7}, {0, 4}, {1, 5}, {2, 6}, {3, 7}};
	for (int k = 0; k + 1 < nz; k++)
		for (int j = 0; j + 1 < ny; j++)
			for (int i = 0; i + 1 < nx; i++) {
				float v[8];
				int inside = 0;
				for (int c = 0; c < 8; c++) {
					v[c] = f[idx(i + corner[c][0], j + corner[c][1], k + corner[c][2])];
					inside += v[c] < 0;
				}
				if (inside == 0 || inside == 8)
					continue;
				V3 sum(0, 0, 0);
				int count = 0;
				for (const auto &e : edge) {
					float a = v[e[0]], b = v[e[1]];
					if ((a < 0) == (b < 0))
						continue;
					float t = a / (a - b);
					V3 pa = point(i + corner[e[0]][0], j + corner[e[0]][1], k + corner[e[0]][2]);
					V3 pb = point(i + corner[e[1]][0], j + corner[e[1]][1], k + corner[e[1]][2]);
					sum += pa + (pb - pa) * t;
					count++;
				}
				cell_vertex[idx(i, j, k)] = int(m.vertices.size());
				m.vertices.push_back(sum * (1.f / float(count)));
			}
	// One quad per grid edge with a sign change, joining the 4 cells around the edge.
	auto quad = [&](int a, int b, int c, int d) {
		if (a < 0 || b < 0 || c < 0 || d < 0)
			return;
		const V3 &pa = m.vertices[size_t(a)], &pb = m.vertices[size_t(b)],
			 &pc = m.vertices[size_t(c)], &pd = m.vertices[size_t(d)];
		if (len(pa - pc) <= len(pb - pd)) {
			m.triangles.push_back(cv::Vec3i(a, b, c));
			m.triangles.push_back(cv::Vec3i(a, c, d));
		} else {
			m.triangles.push_back(cv::Vec3i(a, b, d));
			m.triangles.push_back(cv::Vec3i(b, c, d));
		}
	};
	for (int k = 1; k + 1 < nz; k++)
		for (int j = 1; j + 1 < ny; j++)
			for (int i = 1; i + 1 < nx; i++) {
				bool in = f[idx(i, j, k)] < 0;
				if (in != (f[idx(i + 1, j, k)] < 0))
					quad(cell_vertex[idx(i, j - 1, k - 1)], cell_vertex[idx(i, j, k - 1)],
					     cell_vertex[idx(i, j, k)], cell_vertex[idx(i, j - 1, k)]);
				if (in != (f[idx(i, j + 1, k)] < 0))
					quad(cell_vertex[idx(i - 1, j, k - 1)], cell_vertex[idx(i, j, k - 1)],
					     cell_vertex[idx(i, j, k)], cell_vertex[idx(i - 1, j, k)]);
				if (in != (f[idx(i, j, k + 1)] < 0))
					quad(cell_vertex[idx(i - 1, j - 1, k)], cell_vertex[idx(i, j - 1, k)],
					     cell_vertex[idx(i, j, k)], cell_vertex[idx(i - 1, j, k)]);
			}
	*ret_mesh = std::move(m);
}

void internal::orient_outwards(Mesh *mesh)
{
	Mesh &m = *mesh;
	// The quad winding of surface_nets depends on the crossing sign.
	for (cv::Vec3i &t : m.triangles) {
		const V3 &a = m.vertices[size_t(t[0])], &b = m.vertices[size_t(t[1])], &c = m.vertices[size_t(t[2])];
		V3 n = (b - a).cross(c - a);
		V3 avg = m.normals[size_t(t[0])] + m.normals[size_t(t[1])] + m.normals[size_t(t[2])];
		if (n.dot(avg) < 0)
			std::swap(t[1], t[2]);
	}
}

Status make_head(const HeadSpec &spec, const cv::Vec3f &skin, Mesh *ret_mesh)
{
	if (!(spec.cell_mm >= 0.4 && spec.cell_mm <= 8))
		return Status::error(-EINVAL, "head cell_mm " + std::to_string(spec.cell_mm) +
						      " out of range [0.4, 8]");
	for (const HeadShapeRange &r : head_shape_ranges()) {
		double v = spec.shape.*r.member;
		if (!(v >= r.lo - 1e-9 && v <= r.hi + 1e-9))
			return Status::error(-EINVAL, std::string("head shape ") + r.name + " " +
							      std::to_string(v) + " out of range [" +
							      std::to_string(r.lo) + ", " + std::to_string(r.hi) + "]");
	}
	for (const HeadLookRange &r : head_look_ranges()) {
		double v = spec.look.*r.member;
		// The canonical look's values (freckle_darkness etc.) lie inside their ranges too.
		if (!(v >= r.lo - 1e-9 && v <= r.hi + 1e-9))
			return Status::error(-EINVAL, std::string("head look ") + r.name + " " + std::to_string(v) +
							      " out of range [" + std::to_string(r.lo) + ", " +
							      std::to_string(r.hi) + "]");
	}
	for (int k = 0; k < 3; k++)
		if (!(spec.look.hair[k] >= 0 && spec.look.hair[k] <= 1))
			return Status::error(-EINVAL, "head look hair albedo must lie in 0..1");
	Shape shape = make_shape(spec.shape);
	shape.shoulders = spec.look.shoulders;
	for (int k = 0; k < 3; k++)
		if (!(skin[k] >= 0 && skin[k] <= 1))
			return Status::error(-EINVAL, "skin albedo must lie in 0..1");
	if (!spec.scan_dir.empty())
		return make_scan_head(spec, skin, ret_mesh);
	const float h = float(spec.cell_mm);
	// The canonical head's box, scaled with the head (and widened for the asymmetry).
	const float wx = float(spec.shape.width) * (1 + std::fabs(shape.asym));
	const float bx = shape.shoulders ? 210.f : 104.f, by = shape.shoulders ? -338.f : -212.f;
	const float bz = shape.shoulders ? -140.f : -122.f;
	const V3 lo(-bx * wx, by * float(spec.shape.height), bz * float(spec.shape.depth));
	const V3 hi(bx * wx, 136 * float(spec.shape.height), 132 * float(spec.shape.depth));
	const int nx = int(std::ceil((hi[0] - lo[0]) / h)) + 1;
	const int ny = int(std::ceil((hi[1] - lo[1]) / h)) + 1;
	const int nz = int(std::ceil((hi[2] - lo[2]) / h)) + 1;
	auto idx = [&](int i, int j, int k) { return (size_t(k) * size_t(ny) + size_t(j)) * size_t(nx) + size_t(i); };
	auto point = [&](int i, int j, int k) { return lo + V3(float(i) * h, float(j) * h, float(k) * h); };

	// Coarse pass every 4 samples; fine samples only near the surface (the field is a
	// distance bound, so far samples keep a coarse value with the right sign).
	std::vector<float> f(size_t(nx) * size_t(ny) * size_t(nz), 0.f);
	const int s = 4;
	const int cx = (nx - 1) / s + 2, cy = (ny - 1) / s + 2, cz = (nz - 1) / s + 2;
	std::vector<float> coarse(size_t(cx) * size_t(cy) * size_t(cz));
	cv::parallel_for_(cv::Range(0, cz), [&](const cv::Range &r) {
		for (int k = r.start; k < r.end; k++)
			for (int j = 0; j < cy; j++)
				for (int i = 0; i < cx; i++)
					coarse[(size_t(k) * size_t(cy) + size_t(j)) * size_t(cx) + size_t(i)] =
						head_field(point(i * s, j * s, k * s), shape);
	});
	const float band = float(s) * h * 1.8f;
	cv::parallel_for_(cv::Range(0, nz), [&](const cv::Range &r) {
		for (int k = r.start; k < r.end; k++)
			for (int j = 0; j < ny; j++)
				for (int i = 0; i < nx; i++) {
					int ci = (i + s / 2) / s, cj = (j + s / 2) / s, ck = (k + s / 2) / s;
					float c = coarse[(size_t(ck) * size_t(cy) + size_t(cj)) * size_t(cx) + size_t(ci)];
					f[idx(i, j, k)] = std::fabs(c) > band ? c : head_field(point(i, j, k), shape);
				}
	});

	Mesh m;
	internal::surface_nets(f, nx, ny, nz, lo, h, &m);
	f.clear();
	f.shrink_to_fit();

	settle(&m, h, [&](const V3 &p) { return head_field(p, shape); },
	       [&](const V3 &p) { return field_gradient(p, shape); });
	paint(spec, shape, skin, &m);
	internal::orient_outwards(&m);
	*ret_mesh = std::move(m);
	return Status();
}

} // namespace facescan::sim
