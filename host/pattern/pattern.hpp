// The projected pattern: the code matrix of the seed paper and the slide a projector throws.
//
// A code matrix has `rows` x `cols` cells, each holding one of `letters` code letters. The code
// word of an interior cell is (up, left, centre, right, down); every interior cell's word occurs
// exactly once in the matrix, so a square seen with its 4 neighbours names its cell. Border cells
// are projected too but only decodable through their interior neighbours.
//
// Room to grow: `letters` (more hues) is a parameter throughout; the window is fixed to the
// 5-cell cross here, and a new window shape would be a new CodeWindow value.
#pragma once

#include "common/status.hpp"

#include <opencv2/core.hpp>

#include <cstdint>
#include <string>
#include <vector>

namespace facescan {

enum class CodeWindow { Cross5 };

struct CodeMatrixSpec {
	int letters = 3;
	int rows = 14;	// 12 x 17 = 204 decodable interior cells of the 3^5 = 243 possible
	int cols = 19;	// 19:14 ≈ 4:3, the projector's aspect
	uint32_t seed = 2; // first seed of the search (tries seed, seed+1, ...); 2 succeeds at once
	int attempts = 64; // seeds tried before giving up
	CodeWindow window = CodeWindow::Cross5;
};

class CodeMatrix {
public:
	CodeMatrix() = default;
	CodeMatrix(int rows, int cols, int letters, std::vector<uint8_t> cells);

	int rows() const { return rows_; }
	int cols() const { return cols_; }
	int letters() const { return letters_; }
	/// Letter 0..letters-1 at row r (0 = top of the slide), column c (0 = left).
	uint8_t at(int r, int c) const { return cells_[size_t(r) * size_t(cols_) + size_t(c)]; }
	bool interior(int r, int c) const { return r > 0 && c > 0 && r < rows_ - 1 && c < cols_ - 1; }
	/// Number of interior (decodable) cells.
	int decodable_cells() const { return (rows_ - 2) * (cols_ - 2); }
	/// The code word of an interior cell as a base-`letters` number with digits
	/// (up, left, centre, right, down), most significant first; -1 for border cells.
	int word(int r, int c) const;
	/// Number of distinct code words the window can express: letters^5.
	int word_space() const;
	/// Lookup table word → cell index r*cols+c, -1 where the word does not occur.
	std::vector<int> word_table() const;
	/// True when every interior word is distinct.
	bool unique() const;
	/// Minimum Hamming distance (in letters) between the code words of two distinct interior cells.
	int min_hamming_distance() const;
	const std::vector<uint8_t> &cells() const { return cells_; }

private:
	int rows_ = 0, cols_ = 0, letters_ = 0;
	std::vector<uint8_t> cells_;
};

/// Searches for a matrix of the given size whose interior code words are all distinct (seeded
/// local search; deterministic for a spec). -ETIMEDOUT when none was found within the budget.
Status search_code_matrix(const CodeMatrixSpec &spec, CodeMatrix *ret_matrix,
			  uint32_t *ret_seed = nullptr);
/// search_code_matrix's answer, taken from this build's table of matrices already searched
/// when the spec is one of them (the default is), else searched.
Status generate_code_matrix(const CodeMatrixSpec &spec, CodeMatrix *ret_matrix,
			    uint32_t *ret_seed = nullptr);

/// The hues of the code letters on a 0..255 scale (HSI, the paper's 42.5, 127.5, 212.5 for 3).
double letter_hue(int letter, int letters);
/// HSI → RGB (all on 0..255; H in 0..255 maps to 0..360 degrees). Gonzalez & Woods' sector
/// formulas; values outside the RGB gamut are clipped.
cv::Vec3b hsi_to_rgb(double h, double s, double i);

struct SlideSpec {
	int width = 1024;   // projector resolution
	int height = 768;
	double gap_fraction = 0.30; // black gap between squares, as a fraction of the cell pitch
	double saturation = 255, intensity = 128;
};

/// A pattern: the matrix laid out on a slide of a given resolution.
struct Pattern {
	std::string id;		// names the matrix (letters, size, seed): e.g. "fs-l3-14x19-s2"
	CodeMatrix matrix;
	SlideSpec slide;
	cv::Point2d origin;	// slide pixel of the top-left corner of cell (0,0)'s pitch box
	double pitch = 0;	// slide pixels from one cell to the next
	/// The coloured square of cell (r, c) on the slide, in slide pixels (continuous coordinates:
	/// x0 <= x < x1). The gap lies around it.
	cv::Rect2d cell_rect(int r, int c) const;
	cv::Vec3b letter_rgb(int letter) const;
};

/// Lays the matrix out centred on the slide with square cells as large as fit.
Status make_pattern(const CodeMatrix &matrix, uint32_t seed, const SlideSpec &slide,
		    Pattern *ret_pattern);
/// The default pattern of this build for a slide (the default CodeMatrixSpec).
Status default_pattern(const SlideSpec &slide, Pattern *ret_pattern);
/// Regenerates a pattern from its id; -ENOENT "unknown pattern id" when this build cannot.
Status pattern_from_id(const std::string &id, const SlideSpec &slide, Pattern *ret_pattern);
/// Renders the slide: coloured squares on black, 8-bit BGR (OpenCV order).
cv::Mat render_slide(const Pattern &pattern);

/// pattern.json: id, letters, rows, cols, matrix (rows of letters, row 0 at the top),
/// slide {width, height, pitch, gap_fraction}, hues, and per cell its rectangle on the slide.
Status write_pattern_json(const std::string &path, const Pattern &pattern);
Status read_pattern_json(const std::string &path, Pattern *ret_pattern);

} // namespace facescan
