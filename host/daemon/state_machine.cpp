#include "daemon/state_machine.hpp"

#include <string>

namespace facescan::daemon {

const char *state_name(State s)
{
	switch (s) {
	case State::idle: return "idle";
	case State::armed: return "armed";
	case State::capturing: return "capturing";
	case State::reconstructing: return "reconstructing";
	case State::writing: return "writing";
	case State::error: return "error";
	}
	return "?";
}

const char *event_name(Event e)
{
	switch (e) {
	case Event::request: return "request";
	case Event::fire: return "fire";
	case Event::captured: return "captured";
	case Event::reconstructed: return "reconstructed";
	case Event::written: return "written";
	case Event::failed: return "failed";
	case Event::disarm: return "disarm";
	case Event::fault: return "fault";
	case Event::recovered: return "recovered";
	}
	return "?";
}

bool StateMachine::busy() const
{
	return state_ != State::idle && state_ != State::error;
}

Status StateMachine::apply(Event e)
{
	State s = state_;
	State next = s;
	bool ok = false;
	switch (e) {
	case Event::request:
		if (s == State::idle) {
			next = State::armed;
			ok = true;
		} else if (s == State::error) {
			return Status::error(EAGAIN, "unavailable: the booth is in error");
		} else {
			return Status::error(EBUSY, std::string("busy: ") + state_name(s));
		}
		break;
	case Event::fire:
		if (s == State::armed) {
			next = State::capturing;
			ok = true;
		} else if (s != State::idle && s != State::error) {
			return Status::error(EBUSY, std::string("busy: ") + state_name(s));
		}
		break;
	case Event::captured:
		ok = s == State::capturing;
		next = State::reconstructing;
		break;
	case Event::reconstructed:
		ok = s == State::reconstructing;
		next = State::writing;
		break;
	case Event::written:
		ok = s == State::writing;
		next = State::idle;
		break;
	case Event::failed:
		ok = s == State::armed || s == State::capturing || s == State::reconstructing ||
		     s == State::writing;
		next = State::error;
		break;
	case Event::disarm:
		ok = s == State::armed;
		next = State::idle;
		break;
	case Event::fault:
		ok = s == State::idle || s == State::armed;
		next = State::error;
		break;
	case Event::recovered:
		ok = s == State::error;
		next = State::idle;
		break;
	}
	if (!ok)
		return Status::error(EINVAL, std::string("event ") + event_name(e) + " in state " +
						     state_name(s));
	state_ = next;
	return Status();
}

} // namespace facescan::daemon
