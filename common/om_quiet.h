/* OpenMesh reports refused faces and decimater progress on its own global
 * streams (omerr/omlog). Library code must not print, so the shims silence
 * those streams for the duration of a call and restore them afterwards.
 * C++ only; included by the OpenMesh shims. */
#ifndef MTS_OM_QUIET_H
#define MTS_OM_QUIET_H

#include <OpenMesh/Core/System/omstream.hh>

namespace mts {

class OmQuiet {
public:
    OmQuiet() : err_(::omerr().is_enabled()), log_(::omlog().is_enabled()),
                out_(::omout().is_enabled())
    {
        ::omerr().disable();
        ::omlog().disable();
        ::omout().disable();
    }
    ~OmQuiet()
    {
        if (err_) ::omerr().enable();
        if (log_) ::omlog().enable();
        if (out_) ::omout().enable();
    }
    OmQuiet(const OmQuiet &) = delete;
    OmQuiet &operator=(const OmQuiet &) = delete;

private:
    bool err_, log_, out_;
};

} // namespace mts

#endif
