// Code matrix: construction and properties.
#include "pattern/pattern.hpp"

#include <algorithm>
#include <array>
#include <random>

namespace facescan {

namespace {

constexpr int kWindow = 5;
// Offsets of the cross window in word digit order: up, left, centre, right, down.
constexpr int kDr[kWindow] = {-1, 0, 0, 0, 1};
constexpr int kDc[kWindow] = {0, -1, 0, 1, 0};

int ipow(int base, int exp)
{
	int r = 1;
	while (exp-- > 0)
		r *= base;
	return r;
}

int word_of(const std::vector<uint8_t> &m, int cols, int letters, int r, int c)
{
	int w = 0;
	for (int k = 0; k < kWindow; k++)
		w = w * letters + m[size_t(r + kDr[k]) * size_t(cols) + size_t(c + kDc[k])];
	return w;
}

// One attempt of a min-conflicts local search with random walk: start from a random matrix and
// flip single cells, keeping flips that do not add duplicate words (plus rare uphill moves to
// leave local minima). Deterministic for a seed: std::mt19937 is specified bit-exactly.
bool search(int rows, int cols, int letters, uint32_t seed, long max_steps,
	    std::vector<uint8_t> *ret)
{
	std::mt19937 rng(seed);
	std::vector<uint8_t> m(size_t(rows) * size_t(cols));
	for (auto &x : m)
		x = uint8_t(rng() % uint32_t(letters));
	std::vector<int> count(size_t(ipow(letters, kWindow)), 0);
	auto interior = [&](int r, int c) { return r > 0 && c > 0 && r < rows - 1 && c < cols - 1; };
	// The word of every interior cell, kept current: a flip changes one digit of five words, so
	// each is updated by one product instead of being read again from the matrix (this search
	// runs on every `facescan recon`, which regenerates its pattern from the id).
	std::vector<int> words(m.size(), 0);
	int conflicts = 0;
	for (int r = 1; r < rows - 1; r++)
		for (int c = 1; c < cols - 1; c++) {
			const int w = word_of(m, cols, letters, r, c);
			words[size_t(r) * size_t(cols) + size_t(c)] = w;
			if (count[size_t(w)]++)
				conflicts++;
		}
	// Cell (r, c) is digit 4 - k of the word centred at (r + kDr[k], c + kDc[k]) (the cross is
	// symmetric), whose weight is letters^k.
	int weight[kWindow];
	for (int k = 0; k < kWindow; k++)
		weight[k] = ipow(letters, k);
	// Moves a cell's letter and keeps the words, their counts and the conflict count current.
	auto apply = [&](int r, int c, uint8_t letter) {
		const int change = int(letter) - int(m[size_t(r) * size_t(cols) + size_t(c)]);
		int delta = 0;
		int *centre[kWindow];
		int nc = 0;
		for (int k = 0; k < kWindow; k++) {
			const int rr = r + kDr[k], cc = c + kDc[k];
			if (!interior(rr, cc))
				continue;
			int &w = words[size_t(rr) * size_t(cols) + size_t(cc)];
			if (--count[size_t(w)])
				delta--;
			w += change * weight[k];
			centre[nc++] = &w;
		}
		m[size_t(r) * size_t(cols) + size_t(c)] = letter;
		for (int k = 0; k < nc; k++)
			if (count[size_t(*centre[k])]++)
				delta++;
		return delta;
	};
	for (long step = 0; step < max_steps && conflicts > 0; step++) {
		int i = int(rng() % uint32_t(rows * cols));
		int r = i / cols, c = i % cols;
		uint8_t old = m[size_t(i)];
		uint8_t next = uint8_t((old + 1 + rng() % uint32_t(letters - 1)) % uint32_t(letters));
		int delta = apply(r, c, next);
		if (delta <= 0 || rng() % 1000 < 2)
			conflicts += delta;
		else
			apply(r, c, old);
	}
	if (conflicts)
		return false;
	*ret = std::move(m);
	return true;
}

// Matrices this build has already searched, so a reconstruction does not spend ~130 ms (8 % of
// a scan's wall time on 2 cores) regenerating its slide from the id on every run. Only a cache:
// test_pattern checks each entry against search_code_matrix, so an entry can never name another
// matrix than its spec's search finds.
struct KnownMatrix {
	int letters, rows, cols;
	uint32_t seed;
	const char *cells; // row-major, one digit per letter, row 0 at the top of the slide
};
constexpr KnownMatrix kKnownMatrices[] = {
	{3, 14, 19, 2,
	 "2121012120120110101" "0012000011021210012" "0000121122001022202" "1100121110210020120"
	 "0101000201100202120" "1102201010211212120" "1100220012120201010" "2012202210110202011"
	 "2222002211111122121" "0211201221102100210" "1222102011210020212" "2120221112220001122"
	 "2002101012220222000" "1010022122120011121"},
};

} // namespace

CodeMatrix::CodeMatrix(int rows, int cols, int letters, std::vector<uint8_t> cells)
	: rows_(rows), cols_(cols), letters_(letters), cells_(std::move(cells))
{
}

int CodeMatrix::word(int r, int c) const
{
	if (!interior(r, c))
		return -1;
	return word_of(cells_, cols_, letters_, r, c);
}

int CodeMatrix::word_space() const
{
	return ipow(letters_, kWindow);
}

std::vector<int> CodeMatrix::word_table() const
{
	std::vector<int> table(size_t(word_space()), -1);
	for (int r = 1; r < rows_ - 1; r++)
		for (int c = 1; c < cols_ - 1; c++)
			table[size_t(word(r, c))] = r * cols_ + c;
	return table;
}

bool CodeMatrix::unique() const
{
	std::vector<char> seen(size_t(word_space()), 0);
	for (int r = 1; r < rows_ - 1; r++)
		for (int c = 1; c < cols_ - 1; c++)
			if (seen[size_t(word(r, c))]++)
				return false;
	return true;
}

int CodeMatrix::min_hamming_distance() const
{
	std::vector<std::array<int, kWindow>> words;
	for (int r = 1; r < rows_ - 1; r++)
		for (int c = 1; c < cols_ - 1; c++) {
			std::array<int, kWindow> w{};
			for (int k = 0; k < kWindow; k++)
				w[size_t(k)] = at(r + kDr[k], c + kDc[k]);
			words.push_back(w);
		}
	int best = kWindow;
	for (size_t i = 0; i < words.size(); i++)
		for (size_t j = i + 1; j < words.size(); j++) {
			int d = 0;
			for (int k = 0; k < kWindow; k++)
				d += words[i][size_t(k)] != words[j][size_t(k)];
			best = std::min(best, d);
		}
	return best;
}

Status search_code_matrix(const CodeMatrixSpec &spec, CodeMatrix *ret_matrix, uint32_t *ret_seed)
{
	if (spec.window != CodeWindow::Cross5)
		return Status::error(EINVAL, "only the 5-cell cross window is implemented");
	if (spec.letters < 2 || spec.letters > 8)
		return Status::error(EINVAL, "letters must be 2..8, got " + std::to_string(spec.letters));
	if (spec.rows < 3 || spec.cols < 3 || spec.rows > 256 || spec.cols > 256)
		return Status::error(EINVAL, "matrix must be 3..256 cells a side");
	if ((spec.rows - 2) * (spec.cols - 2) > ipow(spec.letters, kWindow))
		return Status::error(EINVAL, "more interior cells (" +
						     std::to_string((spec.rows - 2) * (spec.cols - 2)) +
						     ") than code words (" +
						     std::to_string(ipow(spec.letters, kWindow)) + ")");
	// Attempts are independent; a few short ones beat one long one for escaping dead ends.
	const long steps_per_attempt = 3000000;
	for (int a = 0; a < spec.attempts; a++) {
		std::vector<uint8_t> cells;
		uint32_t seed = spec.seed + uint32_t(a);
		if (search(spec.rows, spec.cols, spec.letters, seed, steps_per_attempt, &cells)) {
			*ret_matrix = CodeMatrix(spec.rows, spec.cols, spec.letters, std::move(cells));
			if (ret_seed)
				*ret_seed = seed;
			return {};
		}
	}
	return Status::error(ETIMEDOUT, "no unique code matrix of " + std::to_string(spec.rows) + "x" +
						std::to_string(spec.cols) + " found from seed " +
						std::to_string(spec.seed));
}

Status generate_code_matrix(const CodeMatrixSpec &spec, CodeMatrix *ret_matrix, uint32_t *ret_seed)
{
	// The search tries seed, seed + 1, ...: a known matrix found from spec.seed is its answer.
	for (const KnownMatrix &k : kKnownMatrices)
		if (spec.window == CodeWindow::Cross5 && spec.attempts >= 1 && k.letters == spec.letters &&
		    k.rows == spec.rows && k.cols == spec.cols && k.seed == spec.seed) {
			std::vector<uint8_t> cells(size_t(k.rows) * size_t(k.cols));
			for (size_t i = 0; i < cells.size(); i++)
				cells[i] = uint8_t(k.cells[i] - '0');
			*ret_matrix = CodeMatrix(k.rows, k.cols, k.letters, std::move(cells));
			if (ret_seed)
				*ret_seed = k.seed;
			return {};
		}
	return search_code_matrix(spec, ret_matrix, ret_seed);
}

} // namespace facescan
