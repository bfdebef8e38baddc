/* The libcamera backend against the kernel's vimc driver (two instances: two cameras), inside the
 * VM tier (tests/vm/README.md). The contract test_camera.c checks on the fake, on real frames:
 * enumerate, configure fixed exposure and gain, stream N triggers grouped across the cameras,
 * sensor timestamps increasing, each frame's size and pixel format checked against what vimc
 * draws, stop and restart, and a camera unbound while armed reported as an error, not a hang.
 *
 * vimc has no external trigger: its sensors free-run, so the k-th frame after start stands for
 * trigger k and the two cameras' frames of one "trigger" lie up to a frame period apart; the
 * skew bound is opened to 1 s here and the measured skew printed. Outside the VM (no
 * FACESCAN_VM=1) it skips.
 *
 * The suite runs twice: on the libcamera backend in this process, then through the isolated
 * backend (libcamera in a child process, as facescand uses it). In-process, libcamera 0.0.3
 * aborts when a camera vanishes mid-stream (that case is skipped with the reason); isolated, the
 * same unbind must come back as an error, promptly, with this process alive. */
#include <errno.h>
#include <fcntl.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>
#include <cmocka.h>

#include "facescan/camera.h"

/* libcamera's vimc handler takes sizes in multiples of 6 (its scaler scales by 3, the sensor
 * needs even sizes): 636 x 480 is the nearest to VGA it delivers as asked. */
#define W 636
#define H 480
#define N_CAMS 2

static struct fscan_camera *cam;
/* The backend under test: libcamera in this process, or isolated (libcamera in a child). */
static const struct fscan_camera_ops *ops = &fscan_camera_libcamera_ops;
static const struct fscan_camera_params *ops_params;

static double now_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + ts.tv_nsec / 1e9;
}

static int write_sysfs(const char *path, const char *value)
{
	int fd = open(path, O_WRONLY);
	if (fd < 0)
		return -errno;
	ssize_t n = write(fd, value, strlen(value));
	int r = n == (ssize_t)strlen(value) ? 0 : n < 0 ? -errno : -EIO;
	close(fd);
	return r;
}

static void configure(void)
{
	struct fscan_camera_config cfg = {
		.width = W, .height = H, .exposure_us = 10000, .analogue_gain = 1.0f, .max_skew_us = 1000000,
		.external_trigger = true,
	};
	assert_int_equal(fscan_camera_configure(cam, &cfg), 0);
}

/* vimc's sensor draws the 75 % colour bars (v4l2-tpg): white, yellow, cyan, green, magenta, red,
 * blue, black from left to right. Sampling the middle of bars 1 (yellow: R,G high, B low) and 2
 * (cyan: R low) proves the backend delivers R,G,B in that order, whatever libcamera's name. */
static void check_colour_bars(const struct fscan_frame *f)
{
	uint32_t y = f->height / 2;
	const uint8_t *yellow = f->data + (size_t)y * f->stride + (size_t)(f->width * 3 / 16) * 3;
	const uint8_t *cyan = f->data + (size_t)y * f->stride + (size_t)(f->width * 5 / 16) * 3;
	const uint8_t *black = f->data + (size_t)y * f->stride + (size_t)(f->width * 15 / 16) * 3;
	printf("  camera %u: yellow bar (%u,%u,%u) cyan bar (%u,%u,%u) black bar (%u,%u,%u)\n", f->camera,
	       yellow[0], yellow[1], yellow[2], cyan[0], cyan[1], cyan[2], black[0], black[1], black[2]);
	/* The levels are vimc's (bayer sensor, then its debayer): yellow ~(191,143,0), cyan
	 * ~(0,114,95); what matters is which channel is which. */
	assert_true(yellow[0] > 120 && yellow[1] > 80 && yellow[2] < 40);
	assert_true(cyan[0] < 40 && cyan[1] > 80 && cyan[2] > 60);
	assert_true(black[0] < 40 && black[1] < 40 && black[2] < 40);
}

/* Collects n triggers starting at first; checks grouping, size, format, timestamps. Returns the
 * last timestamp of camera 0. */
static uint64_t stream(uint32_t first, uint32_t n, uint64_t after_ns)
{
	uint64_t last[N_CAMS];
	for (int c = 0; c < N_CAMS; c++)
		last[c] = after_ns;
	double t0 = now_s();
	assert_int_equal(fscan_camera_arm(cam, first, n), 0);
	for (uint32_t t = 0; t < n; t++) {
		struct fscan_frame_set *set = NULL;
		int r = fscan_camera_collect(cam, 10000, &set);
		if (r < 0)
			printf("collect trigger %u -> %d (status %d %d)\n", first + t, r, fscan_camera_frame_status(cam, 0),
			       fscan_camera_frame_status(cam, 1));
		assert_int_equal(r, 0);
		assert_int_equal(set->trigger_seq, first + t);
		assert_int_equal(set->count, N_CAMS);
		printf("trigger %u: skew %.1f ms\n", set->trigger_seq, set->skew_ns / 1e6);
		for (uint32_t c = 0; c < N_CAMS; c++) {
			const struct fscan_frame *f = &set->frames[c];
			assert_int_equal(f->camera, c);
			assert_int_equal(f->trigger_seq, first + t);
			assert_int_equal(f->width, W);
			assert_int_equal(f->height, H);
			assert_true(f->stride >= 3 * W);
			assert_true(f->timestamp_ns > last[c]);
			last[c] = f->timestamp_ns;
			if (t == 0)
				check_colour_bars(f);
		}
		fscan_frame_set_free(set);
	}
	double dt = now_s() - t0;
	printf("%u triggers x %d cameras in %.2f s (%.1f frames/s per camera)\n", n, N_CAMS, dt, n / dt);
	/* Every armed trigger was collected. */
	struct fscan_frame_set *set = NULL;
	assert_int_equal(fscan_camera_collect(cam, 10, &set), -ENODATA);
	assert_int_equal(fscan_camera_disarm(cam), 0);
	return last[0];
}

static void test_enumerate(void **state)
{
	(void)state;
	assert_int_equal(fscan_camera_count(cam), N_CAMS);
	for (uint32_t c = 0; c < N_CAMS; c++) {
		struct fscan_camera_info info;
		assert_int_equal(fscan_camera_info(cam, c, &info), 0);
		printf("camera %u: '%s' model '%s' %ux%u\n", c, info.id, info.model, info.width, info.height);
		char want[32];
		snprintf(want, sizeof(want), "vimc.%u", c);
		assert_non_null(strstr(info.id, want)); /* sorted by id, as camera.h says */
		assert_true(info.width > 0 && info.height > 0);
	}
	struct fscan_camera_info info;
	assert_int_equal(fscan_camera_info(cam, N_CAMS, &info), -EINVAL);
}

static void test_configure_rejects_what_the_sensor_cannot(void **state)
{
	(void)state;
	/* A size the pipeline would adjust is refused, not silently replaced: 7 x 5 (below vimc's
	 * minimum) and 640 x 480 (not a multiple of 6: libcamera would make it 636 x 480). */
	struct fscan_camera_config cfg = {.width = 7, .height = 5};
	assert_int_equal(fscan_camera_configure(cam, &cfg), -EINVAL);
	cfg.width = 640;
	cfg.height = 480;
	assert_int_equal(fscan_camera_configure(cam, &cfg), -EINVAL);
	configure();
	struct fscan_camera_info info;
	assert_int_equal(fscan_camera_info(cam, 0, &info), 0);
	assert_int_equal(info.width, W);
	assert_int_equal(info.height, H);
}

static void test_stream_stop_restart(void **state)
{
	(void)state;
	configure();
	uint64_t last = stream(0, 4, 0);
	/* Stop and restart: numbering starts where the caller says; time goes on. */
	last = stream(100, 3, last);
	/* Busy while armed, as the fake. */
	assert_int_equal(fscan_camera_arm(cam, 0, 1), 0);
	assert_int_equal(fscan_camera_arm(cam, 0, 1), -EBUSY);
	struct fscan_camera_config cfg = {0};
	assert_int_equal(fscan_camera_configure(cam, &cfg), -EBUSY);
	assert_int_equal(fscan_camera_disarm(cam), 0);
	assert_int_equal(fscan_camera_arm(cam, 0, 17), -EINVAL);
}

/* Creates the handle under test once libcamera sees both cameras: after camera 1 is bound again,
 * udev takes a moment to announce it, and a manager started earlier sees one camera. */
static int create_both(void)
{
	double t0 = now_s();
	for (;;) {
		int r = fscan_camera_create(ops, ops_params, &cam);
		if (r < 0 || fscan_camera_count(cam) == N_CAMS || now_s() - t0 > 20)
			return r;
		fscan_camera_destroy(cam);
		cam = NULL;
		usleep(500000);
	}
}

/* Binds camera 1 again after a test unbound it, and lets udev announce it. */
static void rebind_camera1(void)
{
	write_sysfs("/sys/bus/platform/drivers/vimc/bind", "vimc.1");
	if (system("udevadm settle -t 15") != 0)
		printf("udevadm settle failed\n");
}

/* collect_first: one trigger is collected before the unbind (the later ones may then have
 * completed already); otherwise the camera goes while all its requests are queued, the case in
 * which libcamera 0.0.3 aborts. */
static void camera_vanishes(bool collect_first)
{
	assert_int_equal(create_both(), 0);
	assert_int_equal(fscan_camera_count(cam), N_CAMS);
	configure();
	/* libcamera's vimc handler gives 4 buffers a stream: at most 4 triggers per arm. */
	assert_int_equal(fscan_camera_arm(cam, 0, 8), -EINVAL);
	assert_int_equal(fscan_camera_arm(cam, 0, 4), 0);
	struct fscan_frame_set *set = NULL;
	if (collect_first) {
		assert_int_equal(fscan_camera_collect(cam, 10000, &set), 0);
		fscan_frame_set_free(set);
		set = NULL;
	}
	/* Pull camera 1 away mid-stream, as a loose cable or a dead sensor would. Frames it
	 * finished before the unbind may still be collected; after that every call fails, promptly
	 * (the alarm in main() catches a hang). */
	assert_int_equal(write_sysfs("/sys/bus/platform/drivers/vimc/unbind", "vimc.1"), 0);
	double t0 = now_s();
	int r = 0, ok = 0;
	for (int i = 0; i < 3 && r == 0; i++) {
		r = fscan_camera_collect(cam, 3000, &set);
		ok += r == 0;
		fscan_frame_set_free(set);
		set = NULL;
	}
	printf("after unbind: %d set(s) still collected, then %d (%s) after %.2f s\n", ok, r, strerror(-r),
	       now_s() - t0);
	assert_true(r == 0 || r == -EIO || r == -ETIMEDOUT || r == -ENODEV);
	if (r < 0)
		assert_true(fscan_camera_frame_status(cam, 1) < 0);
	/* Arming a camera that is gone fails, promptly. */
	t0 = now_s();
	r = fscan_camera_arm(cam, 0, 1);
	printf("arm after unbind -> %d (%s) in %.2f s\n", r, strerror(-r), now_s() - t0);
	if (r == 0) {
		r = fscan_camera_collect(cam, 3000, &set);
		printf("collect -> %d (%s)\n", r, strerror(-r));
		fscan_frame_set_free(set);
	}
	assert_true(r == -ENODEV || r == -EIO || r == -ETIMEDOUT);
	assert_true(now_s() - t0 < 5.0);
	assert_int_equal(fscan_camera_disarm(cam), 0);
	t0 = now_s();
	fscan_camera_destroy(cam);
	cam = NULL;
	printf("destroy after unbind: %.2f s\n", now_s() - t0);
}

/* In a child process: libcamera 0.0.3 aborts the whole process when a device vanishes before it
 * noticed (FATAL "queuedRequests_.empty()" in PipelineHandler::stop(): the gone device never
 * returns the queued buffers). That is skipped with the reason, not passed; a hang or any other
 * death fails. */
static void test_camera_vanishes(void **state)
{
	(void)state;
	/* libcamera's threads do not survive fork(), and a camera is locked to the process that
	 * acquired it: the child opens its own. */
	fscan_camera_destroy(cam);
	cam = NULL;
	fflush(stdout);
	pid_t pid = fork();
	assert_true(pid >= 0);
	if (pid == 0) {
		camera_vanishes(true);
		_exit(0);
	}
	int status = 0;
	double t0 = now_s();
	while (waitpid(pid, &status, WNOHANG) == 0 && now_s() - t0 < 60)
		usleep(100000);
	bool done = now_s() - t0 < 60;
	if (!done) {
		kill(pid, SIGKILL);
		waitpid(pid, &status, 0);
	}
	/* Back for the tests after this one. */
	rebind_camera1();
	assert_true(done); /* no hang */
	if (WIFSIGNALED(status) && WTERMSIG(status) == SIGABRT) {
		printf("camera vanished: libcamera 0.0.3 aborted the process (PipelineHandler::stop asserts "
		       "queuedRequests_.empty()); the backend cannot report an error through it\n");
		skip();
	}
	assert_true(WIFEXITED(status));
	assert_int_equal(WEXITSTATUS(status), 0);
}

/* Isolated: the unbind in this very process, with the requests queued (libcamera's child
 * aborts) and after a first frame set; this process must see errors and live on. */
static void test_camera_vanishes_isolated(void **state)
{
	(void)state;
	fscan_camera_destroy(cam);
	cam = NULL;
	for (int collect_first = 0; collect_first < 2; collect_first++) {
		camera_vanishes(collect_first);
		rebind_camera1();
	}
}

static int run_suite(const char *name, const struct fscan_camera_ops *suite_ops,
		     const struct fscan_camera_params *suite_params)
{
	ops = suite_ops;
	ops_params = suite_params;
	double t0 = now_s();
	int r = create_both();
	printf("%s: create -> %d in %.2f s\n", name, r, now_s() - t0);
	if (r < 0)
		return 1;
	const struct CMUnitTest in_process[] = {
		cmocka_unit_test(test_enumerate),
		cmocka_unit_test(test_configure_rejects_what_the_sensor_cannot),
		cmocka_unit_test(test_stream_stop_restart),
		cmocka_unit_test(test_camera_vanishes),
	};
	const struct CMUnitTest isolated[] = {
		cmocka_unit_test(test_enumerate),
		cmocka_unit_test(test_configure_rejects_what_the_sensor_cannot),
		cmocka_unit_test(test_stream_stop_restart),
		cmocka_unit_test(test_camera_vanishes_isolated),
	};
	if (suite_ops == &fscan_camera_isolated_ops)
		r = cmocka_run_group_tests_name(name, isolated, NULL, NULL);
	else
		r = cmocka_run_group_tests_name(name, in_process, NULL, NULL);
	fscan_camera_destroy(cam);
	cam = NULL;
	return r;
}

int main(void)
{
	if (!getenv("FACESCAN_VM")) {
		fprintf(stderr, "test_vm_camera: skipped: runs inside the VM tier (tests/vm/test_vm.sh), "
				"where vimc gives libcamera two cameras\n");
		return 77;
	}
	/* A hung backend must fail the test, not the tier; and an abort must not lose the output. */
	alarm(240);
	setvbuf(stdout, NULL, _IONBF, 0);
	static const struct fscan_camera_params isolated_libcamera = {.isolated_inner = &fscan_camera_libcamera_ops};
	int r = run_suite("libcamera", &fscan_camera_libcamera_ops, NULL);
	r += run_suite("isolated", &fscan_camera_isolated_ops, &isolated_libcamera);
	return r;
}
