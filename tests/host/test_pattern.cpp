// The code matrix, the slide colours, the layout and pattern.json.
#include "pattern/pattern.hpp"

#include "cmocka.hpp"

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <unistd.h>
#include <set>
#include <string>

using namespace facescan;

static Pattern default_slide_pattern()
{
	Pattern p;
	Status st = default_pattern(SlideSpec{}, &p);
	assert_true(st.ok());
	return p;
}

static void every_interior_word_occurs_once(void **)
{
	Pattern p = default_slide_pattern();
	const CodeMatrix &m = p.matrix;
	std::set<int> words;
	for (int r = 0; r < m.rows(); r++)
		for (int c = 0; c < m.cols(); c++) {
			assert_in_range(m.at(r, c), 0, 2);
			if (m.interior(r, c))
				assert_true(words.insert(m.word(r, c)).second);
			else
				assert_int_equal(m.word(r, c), -1);
		}
	assert_int_equal(int(words.size()), m.decodable_cells());
	assert_true(m.unique());
	// The word table inverts word(): every interior cell found back from its word.
	std::vector<int> table = m.word_table();
	for (int r = 1; r < m.rows() - 1; r++)
		for (int c = 1; c < m.cols() - 1; c++)
			assert_int_equal(table[size_t(m.word(r, c))], r * m.cols() + c);
	std::printf("matrix %dx%d: %d decodable cells of %d code words\n", m.rows(), m.cols(),
		    m.decodable_cells(), m.word_space());
	assert_int_equal(m.decodable_cells(), 204);
}

static void word_digits_are_up_left_centre_right_down(void **)
{
	Pattern p = default_slide_pattern();
	const CodeMatrix &m = p.matrix;
	int r = 5, c = 7;
	int expect = (((m.at(r - 1, c) * 3 + m.at(r, c - 1)) * 3 + m.at(r, c)) * 3 + m.at(r, c + 1)) * 3 +
		     m.at(r + 1, c);
	assert_int_equal(m.word(r, c), expect);
}

static void min_hamming_distance_is_reported(void **)
{
	Pattern p = default_slide_pattern();
	// Distinct words differ in at least one letter; with 204 of 243 words used some pairs
	// differ in exactly one, so the matrix detects no error by itself — decoding relies on the
	// neighbours' words (each letter is part of 5 words) for error detection.
	int d = p.matrix.min_hamming_distance();
	std::printf("min Hamming distance between code words: %d\n", d);
	assert_int_equal(d, 1);
	// A hand-made matrix with a repeated word is detected as not unique.
	std::vector<uint8_t> cells(4 * 4, 0);
	CodeMatrix flat(4, 4, 3, cells);
	assert_false(flat.unique());
}

static void generation_is_deterministic_and_checks_its_spec(void **)
{
	CodeMatrixSpec spec;
	CodeMatrix a, b;
	uint32_t seed_a = 0, seed_b = 0;
	assert_true(generate_code_matrix(spec, &a, &seed_a).ok());
	assert_true(generate_code_matrix(spec, &b, &seed_b).ok());
	assert_int_equal(seed_a, seed_b);
	assert_true(a.cells() == b.cells());
	spec.rows = 20, spec.cols = 20; // 324 interior cells > 243 words
	assert_int_equal(generate_code_matrix(spec, &a).code(), -EINVAL);
	spec = CodeMatrixSpec{};
	spec.letters = 1;
	assert_int_equal(generate_code_matrix(spec, &a).code(), -EINVAL);
	// A smaller matrix with more letters also works: room for larger codes.
	spec = CodeMatrixSpec{};
	spec.letters = 4, spec.rows = 12, spec.cols = 16, spec.seed = 0;
	assert_true(generate_code_matrix(spec, &a).ok());
	assert_true(a.unique());
}

// generate_code_matrix's answer for a spec must be search_code_matrix's, seed included.
static void assert_generated_as_searched(const CodeMatrixSpec &spec)
{
	CodeMatrix generated, searched;
	uint32_t generated_seed = 0, searched_seed = 0;
	assert_true(generate_code_matrix(spec, &generated, &generated_seed).ok());
	assert_true(search_code_matrix(spec, &searched, &searched_seed).ok());
	assert_int_equal(generated_seed, searched_seed);
	assert_int_equal(generated.rows(), searched.rows());
	assert_int_equal(generated.cols(), searched.cols());
	assert_true(generated.cells() == searched.cells());
	assert_true(generated.unique());
}

static void known_matrices_are_what_the_search_finds(void **)
{
	// generate_code_matrix answers the default spec from its table of matrices already
	// searched; that answer must be the search's, or slides projected by an older build would
	// no longer decode.
	assert_generated_as_searched(CodeMatrixSpec{});
	// A spec that is not in the table is searched (and its own seed reported).
	CodeMatrixSpec other;
	other.seed = 3;
	assert_generated_as_searched(other);
}

static void hsi_colours_match_hand_computed_rgb(void **)
{
	// H = 42.5/255 = 60°, S = 1, I = 128/255: sector 0, B = 0, R = I(1 + cos60/cos0) = 1.5 I,
	// G = 3I - R - B = 1.5 I → 1.5 * 128 = 192. The others are the same by symmetry.
	cv::Vec3b y = hsi_to_rgb(42.5, 255, 128), cy = hsi_to_rgb(127.5, 255, 128),
		  mg = hsi_to_rgb(212.5, 255, 128);
	assert_true(y == cv::Vec3b(192, 192, 0));
	assert_true(cy == cv::Vec3b(0, 192, 192));
	assert_true(mg == cv::Vec3b(192, 0, 192));
	// Grey when unsaturated; pure red at H = 0, S = 1, I = 85/255: R = 3I = 255.
	assert_true(hsi_to_rgb(100, 0, 128) == cv::Vec3b(128, 128, 128));
	assert_true(hsi_to_rgb(0, 255, 85) == cv::Vec3b(255, 0, 0));
	assert_float_equal(letter_hue(0, 3), 42.5, 1e-9);
	assert_float_equal(letter_hue(2, 3), 212.5, 1e-9);
}

static void slide_pixels_have_the_letter_colours(void **)
{
	Pattern p = default_slide_pattern();
	cv::Mat slide = render_slide(p);
	assert_int_equal(slide.cols, 1024);
	assert_int_equal(slide.rows, 768);
	for (int r = 0; r < p.matrix.rows(); r++)
		for (int c = 0; c < p.matrix.cols(); c++) {
			cv::Rect2d rc = p.cell_rect(r, c);
			cv::Point centre(int(rc.x + rc.width / 2), int(rc.y + rc.height / 2));
			cv::Vec3b bgr = slide.at<cv::Vec3b>(centre);
			cv::Vec3b rgb = p.letter_rgb(p.matrix.at(r, c));
			assert_true(bgr == cv::Vec3b(rgb[2], rgb[1], rgb[0]));
			// The gap right of the square is black.
			cv::Point gap(int(rc.x + rc.width + 0.3 * p.slide.gap_fraction * p.pitch), centre.y);
			if (gap.x < slide.cols)
				assert_true(slide.at<cv::Vec3b>(gap) == cv::Vec3b(0, 0, 0));
		}
	// The grid is centred and fills one dimension.
	assert_float_equal(p.pitch, 1024.0 / 19, 1e-9);
	assert_true(p.cell_rect(0, 0).x > 0 && p.cell_rect(0, 0).y > 0);
}

static void pattern_json_round_trips_and_rejects_bad_ids(void **)
{
	Pattern p = default_slide_pattern();
	char dir[] = "/tmp/facescan-pattern-XXXXXX";
	assert_non_null(mkdtemp(dir));
	std::string path = std::string(dir) + "/pattern.json";
	assert_true(write_pattern_json(path, p).ok());
	Pattern q;
	Status st = read_pattern_json(path, &q);
	assert_true(st.ok());
	assert_string_equal(q.id.c_str(), p.id.c_str());
	assert_true(q.matrix.cells() == p.matrix.cells());
	assert_float_equal(q.pitch, p.pitch, 1e-9);

	Pattern r;
	st = pattern_from_id("fs-l3-14x19-s999999", SlideSpec{}, &r);
	assert_int_equal(st.code(), -ENOENT);
	assert_non_null(strstr(st.message().c_str(), "unknown pattern id"));
	assert_int_equal(pattern_from_id("gray-code-8", SlideSpec{}, &r).code(), -ENOENT);
	assert_int_equal(pattern_from_id("fs-l3-14x19-s2junk", SlideSpec{}, &r).code(), -ENOENT);
	assert_true(pattern_from_id(p.id, SlideSpec{}, &r).ok());

	FILE *f = fopen(path.c_str(), "w");
	assert_non_null(f);
	fputs("{\"id\": 3}", f);
	fclose(f);
	st = read_pattern_json(path, &r);
	assert_int_equal(st.code(), -EINVAL);
	assert_non_null(strstr(st.message().c_str(), "'id'"));
	unlink(path.c_str());
	rmdir(dir);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(every_interior_word_occurs_once),
		cmocka_unit_test(word_digits_are_up_left_centre_right_down),
		cmocka_unit_test(min_hamming_distance_is_reported),
		cmocka_unit_test(generation_is_deterministic_and_checks_its_spec),
		cmocka_unit_test(known_matrices_are_what_the_search_finds),
		cmocka_unit_test(hsi_colours_match_hand_computed_rgb),
		cmocka_unit_test(slide_pixels_have_the_letter_colours),
		cmocka_unit_test(pattern_json_round_trips_and_rejects_bad_ids),
	};
	return cmocka_run_group_tests(tests, nullptr, nullptr);
}
