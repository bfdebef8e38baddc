// facescan dicom: a mesh as an Encapsulated STL instance, and C-STORE through the DICOM spool.
#include "daemon/patient_id.hpp"
#include "dicom/dicom.hpp"
#include "facescan/outputs.hpp"
#include "mesh_io/mesh_io.hpp"

#include "capture/capture_set.hpp"
#include "common/version.hpp"

#include <getopt.h>

#include <cstdio>
#include <cstring>
#include <string>

namespace facescan::cli {

static void dicom_usage(FILE *out)
{
	std::fprintf(out,
		     "usage: facescan dicom export MESH OUT.dcm --patient ID [--name N] [--accession A]\n"
		     "                             [--study-uid U] [--units mm|m]\n"
		     "       facescan dicom send --pacs AE@HOST:PORT --spool DIR [--calling-ae AE]\n"
		     "                           [--timeout S] [FILE.dcm...]\n"
		     "       facescan dicom show FILE.dcm [--document OUT]\n"
		     "\n"
		     "export  writes MESH (.drc .ply .glb .obj .stl) as an Encapsulated STL instance\n"
		     "        (SOP class 1.2.840.10008.5.1.4.1.1.104.3) in the patient's study.\n"
		     "send    queues the FILEs in the DICOM spool DIR, then sends everything waiting\n"
		     "        there by C-STORE, oldest first. Exit 0: all sent; 3: the PACS did not\n"
		     "        take them (they wait in DIR for the next send); 1: other failure.\n"
		     "show    prints the identity, patient and document of an instance; --document\n"
		     "        writes the encapsulated document (the STL) to OUT.\n"
		     "No output may name the input (exit 2).\n");
}

// "AE@HOST:PORT" → Pacs.
static Status parse_pacs(const std::string &text, dicom::Pacs *pacs)
{
	const size_t at = text.find('@'), colon = text.rfind(':');
	if (at == std::string::npos || colon == std::string::npos || colon < at)
		return Status::error(-EINVAL, "--pacs must be AE@HOST:PORT");
	pacs->called_ae = text.substr(0, at);
	pacs->host = text.substr(at + 1, colon - at - 1);
	const std::string port = text.substr(colon + 1);
	char *end = nullptr;
	const long p = std::strtol(port.c_str(), &end, 10);
	if (port.empty() || *end)
		return Status::error(-EINVAL, "--pacs: port is not a number");
	pacs->port = int(p);
	return dicom::validate_pacs(*pacs);
}

static int export_main(int argc, char **argv)
{
	static const option opts[] = {{"patient", required_argument, nullptr, 'p'},
				      {"name", required_argument, nullptr, 'n'},
				      {"accession", required_argument, nullptr, 'a'},
				      {"study-uid", required_argument, nullptr, 's'},
				      {"units", required_argument, nullptr, 'u'},
				      {nullptr, 0, nullptr, 0}};
	dicom::Subject who;
	mesh_io::Units units = mesh_io::Units::mm;
	for (int opt; (opt = getopt_long(argc, argv, "", opts, nullptr)) != -1;) {
		Status s;
		switch (opt) {
		case 'p': who.patient_id = optarg; break;
		case 'n': who.patient_name = optarg; break;
		case 'a': who.accession = optarg; break;
		case 's': who.study_uid = optarg; break;
		case 'u': s = mesh_io::parse_units(optarg, &units); break;
		default: dicom_usage(stderr); return 2;
		}
		if (!s.ok()) {
			std::fprintf(stderr, "facescan dicom: %s\n", s.message().c_str());
			return 2;
		}
	}
	if (optind + 2 != argc) {
		std::fprintf(stderr, "facescan dicom export: need MESH and OUT.dcm\n");
		return 2;
	}
	Status s = daemon::validate_patient_id(who.patient_id);
	if (s.ok())
		s = dicom::validate_patient_name(who.patient_name);
	if (s.ok())
		s = dicom::validate_accession(who.accession);
	if (s.ok() && !who.study_uid.empty())
		s = dicom::validate_uid(who.study_uid);
	if (!s.ok()) {
		std::fprintf(stderr, "facescan dicom export: %s\n", s.message().c_str());
		return 2;
	}
	const std::string out = argv[optind + 1];
	std::string why;
	if (!check_outputs({{argv[optind], "the mesh being exported"}}, {{out, ".dcm"}}, &why)) {
		std::fprintf(stderr, "facescan dicom export: %s\n", why.c_str());
		return 2;
	}
	recon::Mesh mesh;
	s = mesh_io::read_mesh(argv[optind], units, "", &mesh);
	std::string stl, dcm;
	dicom::Instance inst;
	if (s.ok())
		s = mesh_io::encode_stl(mesh, mesh_io::Units::mm, &stl);
	dicom::Equipment eq;
	eq.software_version = version();
	if (s.ok())
		s = dicom::encode_stl_instance(stl, who, eq, std::chrono::system_clock::now(), &dcm, &inst);
	if (s.ok())
		s = write_file_atomic(out, dcm.data(), dcm.size());
	if (!s.ok()) {
		std::fprintf(stderr, "facescan dicom export: %s\n", s.message().c_str());
		return 1;
	}
	std::printf("facescan dicom: %s: SOP instance %s, study %s, %zu bytes\n", out.c_str(),
		    inst.sop_instance_uid.c_str(), inst.study_uid.c_str(), dcm.size());
	return 0;
}

static int send_main(int argc, char **argv)
{
	static const option opts[] = {{"pacs", required_argument, nullptr, 'P'},
				      {"spool", required_argument, nullptr, 'S'},
				      {"calling-ae", required_argument, nullptr, 'c'},
				      {"timeout", required_argument, nullptr, 't'},
				      {nullptr, 0, nullptr, 0}};
	std::string pacs_text, spool, calling = "FACESCAN";
	int timeout = 10;
	for (int opt; (opt = getopt_long(argc, argv, "", opts, nullptr)) != -1;) {
		switch (opt) {
		case 'P': pacs_text = optarg; break;
		case 'S': spool = optarg; break;
		case 'c': calling = optarg; break;
		case 't': timeout = std::atoi(optarg); break;
		default: dicom_usage(stderr); return 2;
		}
	}
	dicom::Pacs pacs;
	pacs.calling_ae = calling;
	pacs.timeout_s = timeout;
	Status s = parse_pacs(pacs_text, &pacs);
	if (!s.ok() || spool.empty()) {
		std::fprintf(stderr, "facescan dicom send: %s\n", s.ok() ? "--spool DIR is required" : s.message().c_str());
		return 2;
	}
	dicom::Outbox box(spool);
	s = box.open();
	for (int i = optind; s.ok() && i < argc; ++i) {
		std::string bytes;
		dicom::Parsed parsed;
		s = mesh_io::read_file_bytes(argv[i], &bytes);
		if (s.ok())
			s = dicom::parse_instance(bytes, &parsed);
		std::string queued;
		if (s.ok())
			s = box.put(parsed.instance.sop_instance_uid, bytes, "", &queued);
		if (!s.ok())
			s = Status::error(s.code(), std::string(argv[i]) + ": " + s.message());
	}
	if (!s.ok()) {
		std::fprintf(stderr, "facescan dicom send: %s\n", s.message().c_str());
		return 1;
	}
	std::vector<dicom::Outbox::Sent> sent;
	s = box.flush(pacs, &sent);
	for (const dicom::Outbox::Sent &x : sent)
		std::printf("facescan dicom: sent %s to %s\n", x.sop_instance_uid.c_str(), pacs_text.c_str());
	if (!s.ok()) {
		std::fprintf(stderr, "facescan dicom send: %s; %zu instance(s) wait in %s\n", s.message().c_str(),
			     box.pending().size(), spool.c_str());
		return s.code() == -ECONNREFUSED || s.code() == -ETIMEDOUT ? 3 : 1;
	}
	return 0;
}

static int show_main(int argc, char **argv)
{
	static const option opts[] = {{"document", required_argument, nullptr, 'd'}, {nullptr, 0, nullptr, 0}};
	std::string doc_out;
	for (int opt; (opt = getopt_long(argc, argv, "", opts, nullptr)) != -1;) {
		if (opt != 'd') {
			dicom_usage(stderr);
			return 2;
		}
		doc_out = optarg;
	}
	if (optind + 1 != argc) {
		std::fprintf(stderr, "facescan dicom show: need FILE.dcm\n");
		return 2;
	}
	// Any name for the document (its type is in the instance), but never the instance itself.
	std::string why;
	if (!check_outputs({{argv[optind], "the instance being shown"}}, {{doc_out, ""}}, &why)) {
		std::fprintf(stderr, "facescan dicom show: %s\n", why.c_str());
		return 2;
	}
	std::string bytes;
	dicom::Parsed p;
	Status s = mesh_io::read_file_bytes(argv[optind], &bytes);
	if (s.ok())
		s = dicom::parse_instance(bytes, &p);
	if (s.ok() && !doc_out.empty())
		s = write_file_atomic(doc_out, p.document.data(), p.document.size());
	if (!s.ok()) {
		std::fprintf(stderr, "facescan dicom show: %s\n", s.message().c_str());
		return 1;
	}
	std::printf("sop_class_uid %s\nsop_instance_uid %s\nstudy_uid %s\nseries_uid %s\npatient_id %s\n"
		    "patient_name %s\naccession %s\nmime_type %s\ndocument_bytes %zu\n",
		    p.instance.sop_class_uid.c_str(), p.instance.sop_instance_uid.c_str(), p.instance.study_uid.c_str(),
		    p.instance.series_uid.c_str(), p.patient_id.c_str(), p.patient_name.c_str(), p.accession.c_str(),
		    p.mime_type.c_str(), p.document.size());
	return 0;
}

int dicom_main(int argc, char **argv)
{
	if (argc < 2 || !std::strcmp(argv[1], "--help") || !std::strcmp(argv[1], "-h")) {
		dicom_usage(argc < 2 ? stderr : stdout);
		return argc < 2 ? 2 : 0;
	}
	const std::string sub = argv[1];
	optind = 1;
	if (sub == "export")
		return export_main(argc - 1, argv + 1);
	if (sub == "send")
		return send_main(argc - 1, argv + 1);
	if (sub == "show")
		return show_main(argc - 1, argv + 1);
	std::fprintf(stderr, "facescan dicom: unknown subcommand '%s'\n", sub.c_str());
	return 2;
}

} // namespace facescan::cli
