// The daemon's scan state machine, without I/O: the daemon feeds it events and acts on the
// state it lands in.
//
//   idle --request--> armed --fire--> capturing --captured--> reconstructing --reconstructed-->
//   writing --written--> idle
//   armed --disarm--> idle;  any busy state --failed--> error;  idle/armed --fault--> error;
//   error --recovered--> idle.
// One scan at a time: a request or a button press outside idle (or armed, for the button) is
// refused with -EBUSY; a request in error is refused with -EAGAIN until the daemon recovers.
#pragma once

#include "common/status.hpp"

namespace facescan::daemon {

enum class State { idle, armed, capturing, reconstructing, writing, error };
enum class Event { request, fire, captured, reconstructed, written, failed, disarm, fault, recovered };

const char *state_name(State s);
const char *event_name(Event e);

class StateMachine {
public:
	State state() const
	{
		return state_;
	}
	/// True while a scan owns the booth (armed .. writing).
	bool busy() const;
	/// Applies an event. On success the new state is state(); on refusal the state is unchanged
	/// and the Status says why (-EBUSY: another scan runs, -EAGAIN: in error, -EINVAL: the event
	/// makes no sense in this state).
	Status apply(Event e);

private:
	State state_ = State::idle;
};

} // namespace facescan::daemon
