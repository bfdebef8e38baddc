// libFuzzer target (make fuzz): the control socket's request path, as facescand runs it on the
// bytes a client sends: LineReader (framing, kMaxRequest) -> parse_request -> for a scan,
// validate_patient_id -> the JSON reply line.
//
// The input is a byte stream, fed to one LineReader in chunks whose sizes come from the stream
// itself (byte 0, so the same lines arrive split in different places). Invariants besides "no
// crash, no hang, no ballooning": a line is shorter than kMaxRequest and holds no '\n'; a
// too_large reader stays poisoned; a refused request leaves *ret_request untouched; an accepted
// scan has a patient and DICOM fields that pass host/dicom's rules; every reply, including an
// error message quoting the request, serialises (json::dump() throws on invalid UTF-8).
// Seeds: tests/daemon/fuzz_control_seeds/.
#include "daemon/control.hpp"
#include "daemon/patient_id.hpp"
#include "dicom/dicom.hpp"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "fuzz_check.hpp"

using namespace facescan;
using namespace facescan::daemon;

static void reply(const nlohmann::json &j)
{
	std::string s;
	try {
		s = j.dump() + "\n";
	} catch (const nlohmann::json::exception &e) {
		std::fprintf(stderr, "reply does not serialise: %s\n", e.what());
		std::abort();
	}
	CHECK(s.find('\n') == s.size() - 1);
}

static void handle_line(const std::string &line)
{
	CHECK(line.size() < kMaxRequest && line.find('\n') == std::string::npos);
	Request req;
	req.patient = "untouched";
	Status s = parse_request(line, &req);
	if (!s.ok()) {
		CHECK(s.code() < 0 && !s.message().empty());
		CHECK(req.patient == "untouched");
		reply({{"ok", false}, {"error", "bad_request"}, {"message", s.message()}});
		return;
	}
	if (req.cmd != Request::Cmd::scan) {
		CHECK(req.patient.empty() && !req.wait);
		reply({{"ok", true}});
		return;
	}
	CHECK(dicom::validate_patient_name(req.name).ok());
	CHECK(dicom::validate_accession(req.accession).ok());
	CHECK(req.study_uid.empty() || dicom::validate_uid(req.study_uid).ok());
	s = validate_patient_id(req.patient);
	if (!s.ok()) {
		reply({{"ok", false}, {"error", "bad_patient_id"}, {"message", s.message()}});
		return;
	}
	reply({{"ok", true},
	       {"patient", req.patient},
	       {"dicom_name", req.name},
	       {"dicom_accession", req.accession},
	       {"dicom_study_uid", req.study_uid}});
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	if (size == 0)
		return 0;
	const size_t chunk = size_t(data[0] % 64) + 1; // 1..64 bytes per read(), as a socket may give
	const char *p = reinterpret_cast<const char *>(data + 1);
	size_t left = size - 1;
	LineReader r;
	while (true) {
		std::string line;
		LineReader::Result res = r.next(&line);
		if (res == LineReader::Result::line) {
			handle_line(line);
			continue;
		}
		if (res == LineReader::Result::too_large) {
			// The daemon closes the connection; until then the reader must stay refused.
			r.feed("{\"cmd\":\"status\"}\n", 18);
			CHECK(r.next(&line) == LineReader::Result::too_large);
			break;
		}
		if (left == 0)
			break;
		const size_t n = left < chunk ? left : chunk;
		r.feed(p, n);
		p += n;
		left -= n;
	}
	return 0;
}
