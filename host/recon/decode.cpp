// Stage 3: code words → matrix cells, with single-error correction and neighbour agreement.
//
// The default matrix uses 204 of the 243 possible words, so most single letter errors turn one
// valid word into another: a word alone is weak evidence. A cell is therefore accepted only when
// a neighbour's independent decoding agrees with it, and undecoded squares (border cells, squares
// with a missing neighbour or a wrong letter) take the cell their decoded neighbours imply.
#include "recon/image_stages.hpp"

#include <algorithm>
#include <array>

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

struct Decoded {
	std::vector<int> cell;
	std::vector<char> corrected, touched;
	int decoded = 0;
};

// Decodes squares whose neighbours are in the slide's sense.
Decoded decode_core(const std::vector<Square> &sq, const CodeMatrix &m, const std::vector<int> &table,
		    const DecodeParams &params)
{
	const int rows = m.rows(), cols = m.cols(), letters = m.letters();
	const size_t n = sq.size();
	std::vector<Candidate> cand(n);
	std::vector<char> touched(n, 0); // had some evidence of a cell, accepted or not
	for (size_t i = 0; i < n; i++) {
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
	Decoded out;
	out.cell = final_cell;
	out.corrected = corrected;
	out.touched = touched;
	for (size_t i = 0; i < n; i++)
		out.decoded += final_cell[i] >= 0;
	return out;
}

// Connected components of the squares in `mem` (global indices), linked through neighbours
// in either direction that stay inside `mem`.
std::vector<std::vector<int>> linked_parts(const std::vector<Square> &sq, const std::vector<int> &mem)
{
	std::vector<int> in(sq.size(), -1);
	for (int i : mem)
		in[size_t(i)] = 0;
	// Links are not always mutual: a square links to j when j is its nearest in a direction.
	std::vector<std::vector<int>> adj(sq.size());
	for (int i : mem)
		for (int j : sq[size_t(i)].neighbours)
			if (j >= 0 && in[size_t(j)] == 0) {
				adj[size_t(i)].push_back(j);
				adj[size_t(j)].push_back(i);
			}
	std::vector<std::vector<int>> parts;
	for (int s : mem) {
		if (in[size_t(s)] != 0)
			continue;
		parts.emplace_back();
		std::vector<int> stack{s};
		in[size_t(s)] = 1;
		while (!stack.empty()) {
			int i = stack.back();
			stack.pop_back();
			parts.back().push_back(i);
			for (int j : adj[size_t(i)])
				if (in[size_t(j)] == 0) {
					in[size_t(j)] = 1;
					stack.push_back(j);
				}
		}
	}
	return parts;
}

} // namespace

void decode_cells(const Pattern &pattern, const DecodeParams &params, CameraDetections *dets)
{
	std::vector<Square> &sq = dets->squares;
	const CodeMatrix &m = pattern.matrix;
	const std::vector<int> table = m.word_table();
	const size_t n = sq.size();
	// Connected components of the (image-sense) grid: each is one projector's copy, or a part.
	std::vector<int> all(n);
	for (size_t s = 0; s < n; s++)
		all[s] = int(s);
	std::vector<std::vector<int>> members = linked_parts(sq, all);
	std::vector<int> comp(n, -1);
	for (size_t c = 0; c < members.size(); c++)
		for (int i : members[c])
			comp[size_t(i)] = int(c);
	// Directions in clockwise order (up, right, down, left) as indices of Square::neighbours.
	const int cw[4] = {0, 2, 3, 1};
	const int cw_pos[4] = {0, 3, 1, 2}; // inverse of cw
	dets->detected = int(n);
	dets->decoded = dets->corrected = dets->rejected = 0;
	std::vector<int> local(n, -1);
	// Component `mem` (its squares' local indices set) rewritten into the slide's sense for a
	// slide that appears turned `rot` quarter turns clockwise in the image.
	auto oriented = [&](const std::vector<int> &mem, int rot) {
		std::vector<Square> sub;
		sub.reserve(mem.size());
		for (int i : mem) {
			Square s = sq[size_t(i)];
			// Slide direction d appears as image direction d turned `rot` steps clockwise.
			for (int d = 0; d < 4; d++) {
				int img_dir = cw[(cw_pos[d] + rot) % 4];
				int j = sq[size_t(i)].neighbours[size_t(img_dir)];
				// A one-way link can point into another component: its local index
				// belongs to that component's sub-vector.
				s.neighbours[size_t(d)] = j >= 0 && comp[size_t(j)] == comp[size_t(i)] ? local[size_t(j)] : -1;
			}
			// Slide corner k (TL, TR, BR, BL: clockwise) is image corner k + rot.
			for (int k = 0; k < 4; k++)
				s.corners[size_t(k)] = sq[size_t(i)].corners[size_t((k + rot) % 4)];
			sub.push_back(s);
		}
		return sub;
	};
	// The slide may appear rotated by a quarter turn in the image (a projector rolled 90°, a
	// camera on its side): per component, keep the rotation that decodes the most squares.
	const int rotations = params.any_rotation ? 4 : 1;
	std::vector<int> best_rot;
	std::vector<Decoded> best;
	// Returns how many squares the second best rotation decodes; `all`, if given, gets every
	// rotation's decoding.
	auto decode_member = [&](size_t c, std::vector<Decoded> *all) {
		for (size_t k = 0; k < members[c].size(); k++)
			local[size_t(members[c][k])] = int(k);
		int runner_up = 0;
		if (all)
			all->clear();
		for (int rot = 0; rot < rotations; rot++) {
			Decoded d = decode_core(oriented(members[c], rot), m, table, params);
			if (all)
				all->push_back(d);
			if (rot == 0 || d.decoded > best[c].decoded) {
				if (rot > 0)
					runner_up = std::max(runner_up, best[c].decoded);
				best[c] = std::move(d);
				best_rot[c] = rot;
			} else {
				runner_up = std::max(runner_up, d.decoded);
			}
		}
		return runner_up;
	};
	// Two projectors' copies that meet on the face are often linked into one component (the
	// nearest square across the seam passes the neighbour test), and copies rolled by different
	// quarter turns cannot both decode in one rotation: the copy that loses is left undecoded
	// whole (random booths: 100+ squares with correct letters per camera). So the squares the
	// best rotation leaves undecoded are split off into parts of their own; a part that decodes
	// at least `split_min_decoded` squares in its own best rotation becomes a component, and
	// the rest of the split goes back to where it was. Up to one split per projector.
	for (size_t c = 0; c < members.size(); c++) {
		best_rot.resize(members.size(), 0);
		best.resize(members.size());
		std::vector<Decoded> all;
		decode_member(c, &all);
		if (params.split_min_decoded <= 0 || members[c].size() < 2 * size_t(params.split_min_decoded))
			continue;
		for (int split = 0; split < params.max_splits; split++) {
			// Split off: what the best rotation leaves undecoded, and what another rotation
			// decodes together with more of its grid neighbours (the other copy's squares that
			// the best rotation reads, by chance or by propagation, as cells of its own).
			const std::vector<int> mem = members[c];
			for (size_t k = 0; k < mem.size(); k++)
				local[size_t(mem[k])] = int(k);
			auto support = [&](size_t k, const Decoded &d) {
				int n_dec = 0;
				for (int j : sq[size_t(mem[k])].neighbours)
					n_dec += j >= 0 && comp[size_t(j)] == int(c) && d.cell[size_t(local[size_t(j)])] >= 0;
				return n_dec;
			};
			std::vector<int> rest;
			for (size_t k = 0; k < mem.size(); k++) {
				bool out = best[c].cell[k] < 0;
				for (size_t r = 0; r < all.size() && !out; r++)
					out = int(r) != best_rot[c] && all[r].cell[k] >= 0 &&
					      support(k, all[r]) > support(k, best[c]);
				if (out)
					rest.push_back(mem[k]);
			}
			bool any = false;
			for (std::vector<int> &part : linked_parts(sq, rest)) {
				if (part.size() < size_t(params.split_min_decoded))
					continue;
				const size_t id = members.size();
				for (int i : part)
					comp[size_t(i)] = int(id);
				members.push_back(part);
				best_rot.resize(members.size(), 0);
				best.resize(members.size());
				const int runner_up = decode_member(id, nullptr);
				// Four rotations tried on squares that did not decode once: one of them must
				// stand out, or the decodings are chance agreements of wrong letters.
				if (best[id].decoded >= params.split_min_decoded && best[id].decoded >= 2 * runner_up &&
				    best[id].decoded * 4 >= int(part.size())) {
					any = true;
					continue;
				}
				for (int i : part)
					comp[size_t(i)] = int(c);
				members.pop_back();
			}
			if (!any)
				break;
			std::vector<int> kept;
			for (int i : members[c])
				if (comp[size_t(i)] == int(c))
					kept.push_back(i);
			members[c] = std::move(kept);
			decode_member(c, &all);
		}
	}
	std::array<int, 4> decoded_by_rot{};
	for (size_t c = 0; c < members.size(); c++)
		decoded_by_rot[size_t(best_rot[c])] += best[c].decoded;
	// A component with no decoded square (a nose flank, a projector seam) takes the rotation
	// most of the camera's squares decoded in: the projectors and cameras are rigid, so its
	// corners and neighbours are then in the same order as the other camera's, which growing
	// and guided matching (match.cpp) compare side by side.
	const int usual_rot = int(std::max_element(decoded_by_rot.begin(), decoded_by_rot.end()) - decoded_by_rot.begin());
	for (size_t c = 0; c < members.size(); c++) {
		const std::vector<int> &mem = members[c];
		for (size_t k = 0; k < mem.size(); k++)
			local[size_t(mem[k])] = int(k);
		const int rot = best[c].decoded > 0 ? best_rot[c] : usual_rot;
		const std::vector<Square> sub = oriented(mem, rot);
		for (size_t k = 0; k < mem.size(); k++) {
			Square &s = sq[size_t(mem[k])];
			const Square &b = sub[k];
			s.corners = b.corners;
			for (int d = 0; d < 4; d++)
				s.neighbours[size_t(d)] = b.neighbours[size_t(d)] >= 0 ? mem[size_t(b.neighbours[size_t(d)])] : -1;
			s.cell = best[c].cell[k];
			s.corrected = s.cell >= 0 && best[c].corrected[k];
			if (s.cell >= 0) {
				dets->decoded++;
				dets->corrected += s.corrected;
			} else if (best[c].touched[k]) {
				dets->rejected++;
			}
		}
	}
}

} // namespace facescan::recon
