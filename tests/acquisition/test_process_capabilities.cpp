// The capability check that gates Aravis's packet socket (docs/SECURITY.md): the
// "CapEff:" line of /proc/<pid>/status, parsed without trusting its shape.
#include <gtest/gtest.h>

#include <string>

#include "evar/acquisition/process_capabilities.hpp"

using evar::acquisition::effective_capability_in_status;
using evar::acquisition::kCapNetRaw;

TEST(ProcessCapabilities, ReadsTheEffectiveSetNotThePermittedOrBoundingOne) {
  // As for a service granted only CAP_NET_RAW (bit 13 = 0x2000) in its effective set.
  const std::string status =
      "Name:\tevarnode\nUmask:\t0027\nCapInh:\t0000000000000000\nCapPrm:\t000001ffffffffff\n"
      "CapEff:\t0000000000002000\nCapBnd:\t000001ffffffffff\nCapAmb:\t0000000000002000\n";
  EXPECT_EQ(effective_capability_in_status(status, kCapNetRaw), true);
  EXPECT_EQ(effective_capability_in_status(status, 12), false);  // CAP_NET_ADMIN: permitted only
  // An unprivileged user: nothing effective.
  EXPECT_EQ(effective_capability_in_status("CapPrm:\t0000000000000000\nCapEff:\t0000000000000000\n", kCapNetRaw), false);
  // Root: everything.
  EXPECT_EQ(effective_capability_in_status("CapEff:\t000001ffffffffff", kCapNetRaw), true);
}

TEST(ProcessCapabilities, GarbageIsUnknownNotGranted) {
  EXPECT_EQ(effective_capability_in_status("", kCapNetRaw), std::nullopt);
  EXPECT_EQ(effective_capability_in_status("CapEff:\tzz\n", kCapNetRaw), std::nullopt);
  EXPECT_EQ(effective_capability_in_status("CapEff:\n", kCapNetRaw), std::nullopt);
  EXPECT_EQ(effective_capability_in_status("CapEff:\t2000x\n", kCapNetRaw), std::nullopt);
  EXPECT_EQ(effective_capability_in_status("CapEff:\t00000000000020000000000000000000\n", kCapNetRaw), std::nullopt);  // overflow
  EXPECT_EQ(effective_capability_in_status("CapEff:\t2000\n", 64), std::nullopt);
  EXPECT_EQ(effective_capability_in_status("XCapEff:\t2000\n", kCapNetRaw), std::nullopt);
}
