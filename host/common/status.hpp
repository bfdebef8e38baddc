// Status: the result of a library call that can fail — an errno-style code and a message that
// names the cause (the file, the field, the value). Libraries return it; programs decide and log.
#pragma once

#include <cerrno>
#include <string>
#include <utility>

namespace facescan {

class Status {
public:
	Status() = default;
	static Status error(int code, std::string message)
	{
		Status s;
		s.code_ = code > 0 ? -code : (code ? code : -EINVAL);
		s.message_ = std::move(message);
		return s;
	}
	bool ok() const
	{
		return code_ == 0;
	}
	/// 0, or a negative errno (-EINVAL bad input, -ENOENT missing file, -EIO unreadable, ...).
	int code() const
	{
		return code_;
	}
	const std::string &message() const
	{
		return message_;
	}

private:
	int code_ = 0;
	std::string message_;
};

} // namespace facescan
