// CMocka for C++ tests: cmocka.h declares its functions without extern "C".
#pragma once
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
extern "C" {
#include <cmocka.h>
}
