// The scan state machine: the happy path, refusals (busy), failures and recovery, and the full
// table of events × states.
#include "daemon/state_machine.hpp"


#include <cstring>

// cmocka last: its macros (fail, ...) clash with the standard library
#include <cstdarg>
#include <cstddef>
#include <setjmp.h>
extern "C" {
#include <cmocka.h>
}

using namespace facescan::daemon;

static StateMachine in_state(State target)
{
	StateMachine m;
	switch (target) {
	case State::idle:
		break;
	case State::error:
		assert_true(m.apply(Event::fault).ok());
		break;
	case State::writing:
	case State::reconstructing:
	case State::capturing:
	case State::armed:
		assert_true(m.apply(Event::request).ok());
		if (target == State::armed)
			break;
		assert_true(m.apply(Event::fire).ok());
		if (target == State::capturing)
			break;
		assert_true(m.apply(Event::captured).ok());
		if (target == State::reconstructing)
			break;
		assert_true(m.apply(Event::reconstructed).ok());
		break;
	}
	assert_int_equal(static_cast<int>(m.state()), static_cast<int>(target));
	return m;
}

static void test_happy_path(void **)
{
	StateMachine m;
	const Event path[] = {Event::request, Event::fire, Event::captured, Event::reconstructed, Event::written};
	const State want[] = {State::armed, State::capturing, State::reconstructing, State::writing, State::idle};
	for (int i = 0; i < 5; i++) {
		assert_true(m.apply(path[i]).ok());
		assert_int_equal(static_cast<int>(m.state()), static_cast<int>(want[i]));
	}
}

static void test_one_scan_at_a_time(void **)
{
	const State busy[] = {State::armed, State::capturing, State::reconstructing, State::writing};
	for (State s : busy) {
		StateMachine m = in_state(s);
		assert_true(m.busy());
		facescan::Status r = m.apply(Event::request);
		assert_int_equal(r.code(), -EBUSY);
		assert_non_null(std::strstr(r.message().c_str(), "busy"));
		assert_int_equal(static_cast<int>(m.state()), static_cast<int>(s));
	}
	// A second button press while a scan runs is "busy" too; in armed it fires.
	StateMachine m = in_state(State::reconstructing);
	assert_int_equal(m.apply(Event::fire).code(), -EBUSY);
}

static void test_failures_and_recovery(void **)
{
	const State failing[] = {State::armed, State::capturing, State::reconstructing, State::writing};
	for (State s : failing) {
		StateMachine m = in_state(s);
		assert_true(m.apply(Event::failed).ok());
		assert_int_equal(static_cast<int>(m.state()), static_cast<int>(State::error));
		assert_false(m.busy());
		assert_int_equal(m.apply(Event::request).code(), -EAGAIN);
		assert_true(m.apply(Event::recovered).ok());
		assert_int_equal(static_cast<int>(m.state()), static_cast<int>(State::idle));
		assert_true(m.apply(Event::request).ok());
	}
	StateMachine armed = in_state(State::armed);
	assert_true(armed.apply(Event::disarm).ok());
	assert_int_equal(static_cast<int>(armed.state()), static_cast<int>(State::idle));
}

static void test_full_table(void **)
{
	// Allowed transitions; everything else is refused and leaves the state alone.
	struct Row {
		State from;
		Event ev;
		State to;
	};
	const Row allowed[] = {
		{State::idle, Event::request, State::armed},
		{State::idle, Event::fault, State::error},
		{State::armed, Event::fire, State::capturing},
		{State::armed, Event::disarm, State::idle},
		{State::armed, Event::failed, State::error},
		{State::armed, Event::fault, State::error},
		{State::capturing, Event::captured, State::reconstructing},
		{State::capturing, Event::failed, State::error},
		{State::reconstructing, Event::reconstructed, State::writing},
		{State::reconstructing, Event::failed, State::error},
		{State::writing, Event::written, State::idle},
		{State::writing, Event::failed, State::error},
		{State::error, Event::recovered, State::idle},
	};
	const State states[] = {State::idle, State::armed, State::capturing, State::reconstructing, State::writing,
				State::error};
	const Event events[] = {Event::request, Event::fire, Event::captured, Event::reconstructed, Event::written,
				Event::failed, Event::disarm, Event::fault, Event::recovered};
	int checked = 0;
	for (State s : states)
		for (Event e : events) {
			StateMachine m = in_state(s);
			const Row *row = nullptr;
			for (const Row &r : allowed)
				if (r.from == s && r.ev == e)
					row = &r;
			facescan::Status st = m.apply(e);
			if (row) {
				if (!st.ok())
					fail_msg("%s + %s refused: %s", state_name(s), event_name(e), st.message().c_str());
				assert_int_equal(static_cast<int>(m.state()), static_cast<int>(row->to));
			} else {
				if (st.ok())
					fail_msg("%s + %s accepted", state_name(s), event_name(e));
				assert_int_equal(static_cast<int>(m.state()), static_cast<int>(s));
			}
			checked++;
		}
	assert_int_equal(checked, 54);
}

int main()
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_happy_path),
		cmocka_unit_test(test_one_scan_at_a_time),
		cmocka_unit_test(test_failures_and_recovery),
		cmocka_unit_test(test_full_table),
	};
	return cmocka_run_group_tests(tests, nullptr, nullptr);
}
