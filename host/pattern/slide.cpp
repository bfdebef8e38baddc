// The slide: colours of the code letters, the layout of the matrix, pattern ids and pattern.json.
#include "pattern/pattern.hpp"

#include "capture/capture_set.hpp"

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <fstream>

namespace facescan {

double letter_hue(int letter, int letters)
{
	// Evenly spaced hues offset by half a step: 42.5, 127.5, 212.5 of 255 for 3 letters
	// (the paper found these separate better on skin than pure R, G, B).
	return (letter + 0.5) * 255.0 / letters;
}

cv::Vec3b hsi_to_rgb(double h, double s, double i)
{
	const double deg = M_PI / 180.0;
	double H = std::fmod(h / 255.0 * 360.0, 360.0);
	if (H < 0)
		H += 360.0;
	double S = s / 255.0, I = i / 255.0;
	// Gonzalez & Woods: in each 120° sector one channel is I(1-S), one follows the cosine
	// law, the third makes the sum 3I.
	int sector = int(H / 120.0);
	double Hs = H - 120.0 * sector;
	double low = I * (1 - S);
	double high = I * (1 + S * std::cos(Hs * deg) / std::cos((60.0 - Hs) * deg));
	double rest = 3 * I - (low + high);
	double r, g, b;
	switch (sector) {
	case 0: b = low, r = high, g = rest; break;
	case 1: r = low, g = high, b = rest; break;
	default: g = low, b = high, r = rest; break;
	}
	auto to8 = [](double v) { return cv::saturate_cast<uchar>(std::lround(v * 255.0)); };
	return {to8(r), to8(g), to8(b)};
}

cv::Rect2d Pattern::cell_rect(int r, int c) const
{
	double gap = slide.gap_fraction * pitch;
	return {origin.x + c * pitch + gap / 2, origin.y + r * pitch + gap / 2, pitch - gap,
		pitch - gap};
}

cv::Vec3b Pattern::letter_rgb(int letter) const
{
	return hsi_to_rgb(letter_hue(letter, matrix.letters()), slide.saturation, slide.intensity);
}

static std::string pattern_id_of(const CodeMatrix &m, uint32_t seed)
{
	return "fs-l" + std::to_string(m.letters()) + "-" + std::to_string(m.rows()) + "x" +
	       std::to_string(m.cols()) + "-s" + std::to_string(seed);
}

Status make_pattern(const CodeMatrix &matrix, uint32_t seed, const SlideSpec &slide,
		    Pattern *ret_pattern)
{
	if (slide.width < matrix.cols() * 4 || slide.height < matrix.rows() * 4)
		return Status::error(EINVAL, "slide " + std::to_string(slide.width) + "x" +
						     std::to_string(slide.height) +
						     " is too small for the matrix");
	if (!(slide.gap_fraction >= 0 && slide.gap_fraction < 0.9))
		return Status::error(EINVAL, "gap fraction must be in [0, 0.9)");
	Pattern p;
	p.id = pattern_id_of(matrix, seed);
	p.matrix = matrix;
	p.slide = slide;
	p.pitch = std::min(double(slide.width) / matrix.cols(), double(slide.height) / matrix.rows());
	p.origin = {(slide.width - p.pitch * matrix.cols()) / 2,
		    (slide.height - p.pitch * matrix.rows()) / 2};
	*ret_pattern = std::move(p);
	return {};
}

Status default_pattern(const SlideSpec &slide, Pattern *ret_pattern)
{
	CodeMatrixSpec spec;
	CodeMatrix m;
	uint32_t seed = 0;
	Status st = generate_code_matrix(spec, &m, &seed);
	if (!st.ok())
		return st;
	return make_pattern(m, seed, slide, ret_pattern);
}

Status pattern_from_id(const std::string &id, const SlideSpec &slide, Pattern *ret_pattern)
{
	int letters = 0, rows = 0, cols = 0, used = 0;
	unsigned seed = 0;
	if (std::sscanf(id.c_str(), "fs-l%d-%dx%d-s%u%n", &letters, &rows, &cols, &seed, &used) != 4 ||
	    size_t(used) != id.size())
		return Status::error(ENOENT, "unknown pattern id '" + id + "'");
	CodeMatrixSpec spec;
	spec.letters = letters;
	spec.rows = rows;
	spec.cols = cols;
	spec.seed = seed;
	spec.attempts = 1;
	CodeMatrix m;
	uint32_t found = 0;
	Status st = generate_code_matrix(spec, &m, &found);
	// The id names the seed that produced the matrix; any other outcome is another matrix.
	if (!st.ok() || found != seed)
		return Status::error(ENOENT, "unknown pattern id '" + id + "': this build cannot regenerate it");
	return make_pattern(m, seed, slide, ret_pattern);
}

cv::Mat render_slide(const Pattern &p)
{
	cv::Mat img(p.slide.height, p.slide.width, CV_8UC3, cv::Scalar::all(0));
	for (int r = 0; r < p.matrix.rows(); r++)
		for (int c = 0; c < p.matrix.cols(); c++) {
			cv::Rect2d rc = p.cell_rect(r, c);
			// A pixel is lit when its centre lies inside the square.
			int x0 = int(std::ceil(rc.x - 0.5)), x1 = int(std::ceil(rc.x + rc.width - 0.5));
			int y0 = int(std::ceil(rc.y - 0.5)), y1 = int(std::ceil(rc.y + rc.height - 0.5));
			cv::Vec3b rgb = p.letter_rgb(p.matrix.at(r, c));
			img(cv::Range(std::max(y0, 0), std::min(y1, img.rows)),
			    cv::Range(std::max(x0, 0), std::min(x1, img.cols)))
				.setTo(cv::Scalar(rgb[2], rgb[1], rgb[0]));
		}
	return img;
}

Status write_pattern_json(const std::string &path, const Pattern &p)
{
	using nlohmann::json;
	json j;
	j["id"] = p.id;
	j["letters"] = p.matrix.letters();
	j["rows"] = p.matrix.rows();
	j["cols"] = p.matrix.cols();
	j["window"] = "cross5: up, left, centre, right, down";
	j["decodable_cells"] = p.matrix.decodable_cells();
	j["min_hamming_distance"] = p.matrix.min_hamming_distance();
	json hues = json::array(), rgb = json::array();
	for (int l = 0; l < p.matrix.letters(); l++) {
		hues.push_back(letter_hue(l, p.matrix.letters()));
		cv::Vec3b c = p.letter_rgb(l);
		rgb.push_back({c[0], c[1], c[2]});
	}
	j["hues"] = hues;
	j["rgb"] = rgb;
	j["slide"] = {{"width", p.slide.width},
		      {"height", p.slide.height},
		      {"pitch", p.pitch},
		      {"origin", {p.origin.x, p.origin.y}},
		      {"gap_fraction", p.slide.gap_fraction},
		      {"saturation", p.slide.saturation},
		      {"intensity", p.slide.intensity}};
	json matrix = json::array(), cells = json::array();
	for (int r = 0; r < p.matrix.rows(); r++) {
		json row = json::array();
		for (int c = 0; c < p.matrix.cols(); c++) {
			row.push_back(p.matrix.at(r, c));
			cv::Rect2d rc = p.cell_rect(r, c);
			cells.push_back({{"row", r},
					 {"col", c},
					 {"letter", p.matrix.at(r, c)},
					 {"word", p.matrix.word(r, c)},
					 {"rect", {rc.x, rc.y, rc.width, rc.height}}});
		}
		matrix.push_back(row);
	}
	j["matrix"] = matrix;
	j["cells"] = cells;
	std::string text = j.dump(1) + "\n";
	return write_file_atomic(path, text.data(), text.size());
}

Status read_pattern_json(const std::string &path, Pattern *ret_pattern)
{
	std::ifstream in(path);
	if (!in)
		return Status::error(ENOENT, path + ": cannot open");
	nlohmann::json j = nlohmann::json::parse(in, nullptr, false);
	if (j.is_discarded() || !j.is_object())
		return Status::error(EINVAL, path + ": not a JSON object");
	if (!j.contains("id") || !j["id"].is_string())
		return Status::error(EINVAL, path + ": missing or invalid field 'id'");
	SlideSpec slide;
	try {
		const auto &s = j.at("slide");
		slide.width = s.at("width").get<int>();
		slide.height = s.at("height").get<int>();
		slide.gap_fraction = s.at("gap_fraction").get<double>();
	} catch (const nlohmann::json::exception &) {
		return Status::error(EINVAL, path + ": missing or invalid field 'slide'");
	}
	Pattern p;
	Status st = pattern_from_id(j["id"].get<std::string>(), slide, &p);
	if (!st.ok())
		return Status::error(st.code(), path + ": " + st.message());
	// The matrix in the file must be the one the id names.
	const auto &rows = j.value("matrix", nlohmann::json());
	bool same = rows.is_array() && int(rows.size()) == p.matrix.rows();
	for (int r = 0; same && r < p.matrix.rows(); r++) {
		const auto &row = rows[size_t(r)];
		same = row.is_array() && int(row.size()) == p.matrix.cols();
		for (int c = 0; same && c < p.matrix.cols(); c++)
			same = row[size_t(c)].is_number_integer() && row[size_t(c)].get<int>() == p.matrix.at(r, c);
	}
	if (!same)
		return Status::error(EINVAL, path + ": field 'matrix' does not match pattern id " + p.id);
	*ret_pattern = std::move(p);
	return {};
}

} // namespace facescan
