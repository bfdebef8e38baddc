// Stage 3: code words → matrix cells, with single-error correction and neighbour agreement.
//
// The default matrix uses 204 of the 243 possible words, so most single letter errors turn one
// valid word into another: a word alone is weak evidence. A cell is therefore accepted only when
// a neighbour's independent decoding agrees with it, and undecoded squares (border cells, squares
// with a missing neighbour or a wrong letter) take the cell their decoded neighbours imply.
#include "recon/image_stages.hpp"

#include <algorithm>

namespace facescan::recon {

namespace {

constexpr int kDr[4] = {-1, 0, 0, 1}; // up, left, right, down
constexpr int kDc[4] = {0, -1, 1, 0};

struct Candidate {
	int cell = -1;
	bool corrected = false;
	bool error = false; // a word was read but no unique cell fits it
};

Candidate decode_word(const std::vector<Square> &sq, size_t i, int letters,
		      const std::vector<int> &table, bool correct)
{
	// Word digit order: up, left, centre, right, down.
	const int order[5] = {0, 1, -1, 2, 3};
	int digit[5];
	float conf[5];
	int missing = -1, nmissing = 0;
	for (int p = 0; p < 5; p++) {
		const Square *s = nullptr;
		if (order[p] < 0)
			s = &sq[i];
		else if (sq[i].neighbours[size_t(order[p])] >= 0)
			s = &sq[size_t(sq[i].neighbours[size_t(order[p])])];
		digit[p] = s ? s->letter : -1;
		conf[p] = s ? s->confidence : 0;
		if (digit[p] < 0) {
			missing = p;
			nmissing++;
		}
	}
	Candidate out;
	if (nmissing > 1)
		return out;
	auto encode = [&](const int *d) {
		int w = 0;
		for (int p = 0; p < 5; p++)
			w = w * letters + d[p];
		return w;
	};
	if (nmissing == 0) {
		int cell = table[size_t(encode(digit))];
		if (cell >= 0) {
			out.cell = cell;
			return out;
		}
	}
	if (!correct) {
		out.error = true;
		return out;
	}
	// One wrong or missing letter: the cells reachable by changing one position.
	int weakest = missing;
	if (nmissing == 0) {
		weakest = 0;
		for (int p = 1; p < 5; p++)
			if (conf[p] < conf[weakest])
				weakest = p;
	}
	auto try_position = [&](int p, std::vector<int> *cells) {
		int d[5];
		std::copy(digit, digit + 5, d);
		for (int l = 0; l < letters; l++) {
			if (l == digit[p])
				continue;
			d[p] = l;
			int cell = table[size_t(encode(d))];
			if (cell >= 0 && std::find(cells->begin(), cells->end(), cell) == cells->end())
				cells->push_back(cell);
		}
	};
	std::vector<int> cells;
	if (nmissing == 1) {
		try_position(missing, &cells);
	} else {
		for (int p = 0; p < 5; p++)
			try_position(p, &cells);
		if (cells.size() > 1) { // ambiguous: trust the least confident letter to be the wrong one
			cells.clear();
			try_position(weakest, &cells);
		}
	}
	if (cells.size() == 1) {
		out.cell = cells[0];
		out.corrected = true;
	} else {
		out.error = true;
	}
	return out;
}

} // namespace

void decode_cells(const Pattern &pattern, const DecodeParams &params, CameraDetections *dets)
{
	std::vector<Square> &sq = dets->squares;
	const CodeMatrix &m = pattern.matrix;
	const int rows = m.rows(), cols = m.cols(), letters = m.letters();
	const std::vector<int> table = m.word_table();
	const size_t n = sq.size();
	std::vector<Candidate> cand(n);
	std::vector<char> touched(n, 0); // had some evidence of a cell, accepted or not
	for (size_t i = 0; i < n; i++) {
		sq[i].cell = -1;
		sq[i].corrected = false;
		if (letters > 0 && !table.empty())
			cand[i] = decode_word(sq, i, letters, table, params.correct);
		touched[i] = cand[i].cell >= 0 || cand[i].error;
	}
	auto neighbour_cell = [&](int cell, int d) {
		int r = cell / cols + kDr[d], c = cell % cols + kDc[d];
		return (r < 0 || c < 0 || r >= rows || c >= cols) ? -2 : r * cols + c;
	};
	// Neighbour agreement between the words' own candidates.
	std::vector<int> cell(n, -1);
	std::vector<char> corrected(n, 0);
	for (size_t i = 0; i < n; i++) {
		if (cand[i].cell < 0)
			continue;
		int support = 0, conflict = 0;
		for (int d = 0; d < 4; d++) {
			int j = sq[i].neighbours[size_t(d)];
			if (j < 0 || cand[size_t(j)].cell < 0)
				continue;
			if (cand[size_t(j)].cell == neighbour_cell(cand[i].cell, d))
				support++;
			else
				conflict++;
		}
		if (support >= params.min_support && support > conflict) {
			cell[i] = cand[i].cell;
			corrected[i] = cand[i].corrected;
		}
	}
	// Propagation: a square takes the cell its decoded neighbours agree on.
	for (int round = 0; round < params.propagate_rounds; round++) {
		std::vector<int> next = cell;
		bool changed = false;
		for (size_t i = 0; i < n; i++) {
			if (cell[i] >= 0)
				continue;
			int implied = -1, votes = 0;
			bool conflict = false;
			for (int d = 0; d < 4; d++) {
				int j = sq[i].neighbours[size_t(d)];
				if (j < 0 || cell[size_t(j)] < 0)
					continue;
				// j is our neighbour in direction d, so we are j's neighbour in 3 - d.
				int c = neighbour_cell(cell[size_t(j)], 3 - d);
				if (c < 0 || (implied >= 0 && c != implied))
					conflict = true;
				implied = c;
				votes++;
			}
			if (!votes)
				continue;
			touched[i] = 1;
			if (conflict || implied < 0)
				continue;
			bool letter_ok = sq[i].letter == m.at(implied / cols, implied % cols);
			if (!letter_ok && votes < 2)
				continue;
			next[i] = implied;
			corrected[i] = !letter_ok;
			changed = true;
		}
		cell.swap(next);
		if (!changed)
			break;
	}
	// Final agreement check: drop a cell that no decoded neighbour supports but one contradicts.
	std::vector<int> final_cell = cell;
	for (size_t i = 0; i < n; i++) {
		if (cell[i] < 0)
			continue;
		int support = 0, conflict = 0;
		for (int d = 0; d < 4; d++) {
			int j = sq[i].neighbours[size_t(d)];
			if (j < 0 || cell[size_t(j)] < 0)
				continue;
			if (cell[size_t(j)] == neighbour_cell(cell[i], d))
				support++;
			else
				conflict++;
		}
		if (conflict > support)
			final_cell[i] = -1;
	}
	dets->detected = int(n);
	dets->decoded = dets->corrected = dets->rejected = 0;
	for (size_t i = 0; i < n; i++) {
		sq[i].cell = final_cell[i];
		sq[i].corrected = final_cell[i] >= 0 && corrected[i];
		if (final_cell[i] >= 0) {
			dets->decoded++;
			dets->corrected += sq[i].corrected;
		} else if (touched[i]) {
			dets->rejected++;
		}
	}
}

} // namespace facescan::recon
