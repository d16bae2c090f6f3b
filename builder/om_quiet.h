/* OpenMesh reports refused faces and decimater progress on its own global
 * streams (omerr/omlog). Library code must not print, so the shims silence
 * those streams for the duration of a call and restore them afterwards.
 * The streams are process-wide, so the silencing is counted under a lock:
 * the first call in saves and disables, the last one out restores. Without
 * the count, two calls overlapping in two threads (a server building models
 * while loading others) would restore each other's state out of order and
 * leave OpenMesh printing, or silenced for good. C++ only; included by the
 * OpenMesh shims. */
#ifndef MTS_OM_QUIET_H
#define MTS_OM_QUIET_H

#include <mutex>

#include <OpenMesh/Core/System/omstream.hh>

namespace mts {

class OmQuiet {
public:
    OmQuiet()
    {
        std::lock_guard<std::mutex> lock(state().mutex);
        State &s = state();
        if (s.depth++ == 0) {
            s.err = ::omerr().is_enabled();
            s.log = ::omlog().is_enabled();
            s.out = ::omout().is_enabled();
            ::omerr().disable();
            ::omlog().disable();
            ::omout().disable();
        }
    }
    ~OmQuiet()
    {
        std::lock_guard<std::mutex> lock(state().mutex);
        State &s = state();
        if (--s.depth == 0) {
            if (s.err) ::omerr().enable();
            if (s.log) ::omlog().enable();
            if (s.out) ::omout().enable();
        }
    }
    OmQuiet(const OmQuiet &) = delete;
    OmQuiet &operator=(const OmQuiet &) = delete;

private:
    struct State {
        std::mutex mutex;
        unsigned depth = 0;
        bool err = false, log = false, out = false;
    };
    static State &state()
    {
        static State s; /* one for the process, like the streams it guards */
        return s;
    }
};

} // namespace mts

#endif
