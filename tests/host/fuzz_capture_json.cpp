// libFuzzer target (make fuzz): the capture set's capture.json reader, parse_capture_meta()
// (read_capture_set() once it has the file's bytes), on nlohmann::json.
//
// The input is the whole text of a capture.json, read for a 2-camera and a 3-camera set.
// Invariants besides "no crash, no hang, no ballooning": a refusal names the file; an accepted
// file has both ids, per-camera arrays of exactly one entry per camera (or none), and a trigger
// report that parses back as JSON (write_capture_set() re-parses it). Seeds:
// tests/host/fuzz_capture_json_seeds/.
#include "capture/capture_set.hpp"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "fuzz_check.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	const std::string text(reinterpret_cast<const char *>(data), size);
	const std::string name = "fuzz/capture.json";
	for (size_t n : {size_t(2), size_t(3)}) {
		facescan::CaptureMeta m;
		m.scan_id = "untouched";
		facescan::Status st = facescan::parse_capture_meta(text, name, n, &m);
		if (!st.ok()) {
			CHECK(st.code() < 0);
			CHECK(st.message().compare(0, name.size() + 1, name + ":") == 0);
			CHECK(m.scan_id == "untouched");
			continue;
		}
		CHECK(!m.scan_id.empty() && !m.pattern_id.empty());
		CHECK(m.timestamps_ns.empty() || m.timestamps_ns.size() == n);
		CHECK(m.exposure_us.empty() || m.exposure_us.size() == n);
		if (!m.trigger_report_json.empty())
			CHECK(!nlohmann::json::parse(m.trigger_report_json, nullptr, false).is_discarded());
	}
	return 0;
}
