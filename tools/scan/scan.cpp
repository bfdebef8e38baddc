// facescan scan --patient ID: asks facescand for a scan and follows it to the end.
#include "daemon/client.hpp"
#include "daemon/patient_id.hpp"
#include "dicom/dicom.hpp"
#include "daemon/report_text.hpp"

#include <cstdio>
#include <cstdlib>
#include <getopt.h>
#include <string>

namespace facescan::cli {

int scan_main(int argc, char **argv)
{
	static const option opts[] = {{"patient", required_argument, nullptr, 'p'},
				      {"socket", required_argument, nullptr, 's'},
				      {"json", no_argument, nullptr, 'j'},
				      {"no-wait", no_argument, nullptr, 'n'},
				      {"timeout", required_argument, nullptr, 't'},
				      {"press", no_argument, nullptr, 'b'},
				      {"help", no_argument, nullptr, 'h'},
				      {"name", required_argument, nullptr, 'N'},
				      {"accession", required_argument, nullptr, 'A'},
				      {"study-uid", required_argument, nullptr, 'U'},
				      {nullptr, 0, nullptr, 0}};
	std::string name, accession, study_uid;
	bool study_uid_given = false;
	std::string patient, sock = daemon::default_socket_path();
	bool as_json = false, wait = true, press = false;
	int timeout_s = 600;
	int c;
	optind = 1;
	while ((c = getopt_long(argc, argv, "p:s:jnt:bh", opts, nullptr)) != -1) {
		switch (c) {
		case 'p':
			patient = optarg;
			break;
		case 's':
			sock = optarg;
			break;
		case 'N':
			name = optarg;
			break;
		case 'A':
			accession = optarg;
			break;
		case 'U':
			study_uid = optarg;
			study_uid_given = true;
			break;
		case 'j':
			as_json = true;
			break;
		case 'n':
			wait = false;
			break;
		case 'b':
			press = true;
			break;
		case 't':
			timeout_s = std::atoi(optarg);
			if (timeout_s <= 0) {
				std::fprintf(stderr, "facescan scan: --timeout needs a positive number of seconds\n");
				return 2;
			}
			break;
		case 'h':
			std::printf("usage: facescan scan --patient ID [--name N] [--accession A] [--study-uid U]\n"
				    "                     [--no-wait] [--press] [--json] [--socket PATH] [--timeout S]\n"
				    "Asks facescand for a scan (clinic mode: now; booth mode: at the next button press)\n"
				    "and prints its progress and result. Exit 0 when the scan is delivered or spooled.\n"
				    "  -p, --patient ID  patient id: letters, digits, '.', '_', '-' (max 64)\n"
				    "      --name N      patient name for DICOM, Family^Given^Middle^Prefix^Suffix\n"
				    "                    (UTF-8, max 64 bytes, no '\\' or '=')\n"
				    "      --accession A accession number of the order (max 16 printable ASCII)\n"
				    "      --study-uid U study instance UID to file the scan in (digits and dots,\n"
				    "                    max 64); default: a new study\n"
				    "  -n, --no-wait     return once the daemon accepted the scan\n"
				    "  -b, --press       booth mode: then press the simulated button (fake MCU or\n"
				    "                    an emulated firmware board)\n"
				    "  -j, --json        print the daemon's JSON replies\n"
				    "  -s, --socket PATH control socket (default $FACESCAN_SOCKET or %s)\n"
				    "  -t, --timeout S   give up waiting after S seconds (default 600)\n",
				    daemon::default_socket_path().c_str());
			return 0;
		default:
			std::fprintf(stderr, "facescan scan: bad arguments (see facescan scan --help)\n");
			return 2;
		}
	}
	if (optind < argc) {
		std::fprintf(stderr, "facescan scan: unexpected argument '%s'\n", argv[optind]);
		return 2;
	}
	if (patient.empty()) {
		std::fprintf(stderr, "facescan scan: --patient ID is required\n");
		return 2;
	}
	Status v = daemon::validate_patient_id(patient);
	if (v.ok())
		v = dicom::validate_patient_name(name);
	if (v.ok())
		v = dicom::validate_accession(accession);
	if (v.ok() && study_uid_given)
		v = dicom::validate_uid(study_uid);
	if (!v.ok()) {
		std::fprintf(stderr, "facescan scan: %s\n", v.message().c_str());
		return 2;
	}
	int rc = 1;
	nlohmann::json req = {{"cmd", "scan"}, {"patient", patient}, {"wait", wait}};
	if (!name.empty())
		req["name"] = name;
	if (!accession.empty())
		req["accession"] = accession;
	if (!study_uid.empty())
		req["study_uid"] = study_uid;
	Status s = daemon::control_request(
		sock, req,
		[&](const nlohmann::json &j) {
			if (as_json)
				std::printf("%s\n", j.dump().c_str());
			if (j.contains("ok") && !j.contains("event")) { // the reply to the request
				if (!j["ok"].get<bool>()) {
					if (!as_json)
						std::fprintf(stderr, "facescan scan: %s\n", j.value("message", "refused").c_str());
					return false;
				}
				if (!as_json)
					std::printf("scan %s accepted (%s)\n", j.value("scan_id", "").c_str(),
						    j.value("state", "").c_str());
				if (press && j.value("state", "") == "armed") {
					Status b = daemon::control_request(
						sock, {{"cmd", "button"}},
						[&](const nlohmann::json &r) {
							if (!r.value("ok", false))
								std::fprintf(stderr, "facescan scan: button: %s\n",
									     r.value("message", "refused").c_str());
							return false;
						},
						5000);
					if (!b.ok())
						std::fprintf(stderr, "facescan scan: button: %s\n", b.message().c_str());
				}
				rc = wait ? 1 : 0;
				return wait;
			}
			const std::string ev = j.value("event", "");
			if (ev == "progress") {
				if (!as_json)
					std::printf("  %s\n", j.value("message", "").c_str());
				return true;
			}
			if (ev == "done") {
				if (!as_json)
					std::printf("%s", daemon::scan_text(j["scan"]).c_str());
				rc = j.value("ok", false) ? 0 : 1;
				return false;
			}
			return true;
		},
		timeout_s * 1000);
	if (!s.ok()) {
		std::fprintf(stderr, "facescan scan: %s\n", s.message().c_str());
		return 1;
	}
	std::fflush(stdout);
	return rc;
}

} // namespace facescan::cli
