#pragma once
// A C-arm adapter on USB emulated by umockdev: the device appears in a mocked sysfs and
// /dev/bus/usb, and its usbfs ioctls (SUBMITURB, REAPURB, DISCARDURB, ...) are answered here
// as the adapter's firmware would, carrying C-arm link frames on a bulk IN endpoint. A
// program using it must run under umockdev's preload library (usb/umockdev_main.cpp).
#include <gtest/gtest.h>
#include <linux/ioctl.h>
#include <linux/usbdevice_fs.h>
#include <umockdev.h>

#include <algorithm>
#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <deque>
#include <mutex>
#include <string>
#include <vector>

namespace evar::test {

constexpr std::uint16_t kVendor = 0x1209, kProduct = 0xea01;  // pid.codes test ids

// Device and configuration descriptors: one vendor-specific interface with a bulk IN
// endpoint 0x81 and a bulk OUT endpoint 0x01, 64-byte packets (full speed).
inline std::string descriptor_hex() {
  const std::vector<std::uint8_t> d = {
      18, 1, 0x00, 0x02, 0, 0, 0, 64, kVendor & 0xFF, kVendor >> 8, kProduct & 0xFF, kProduct >> 8, 0x00, 0x01, 0, 0, 0, 1,
      9, 2, 32, 0, 1, 1, 0, 0x80, 50,
      9, 4, 0, 0, 2, 0xFF, 0, 0, 0,
      7, 5, 0x81, 0x02, 64, 0, 0,
      7, 5, 0x01, 0x02, 64, 0, 0};
  std::string s;
  char b[3];
  for (auto v : d) {
    std::snprintf(b, sizeof b, "%02x", v);
    s += b;
  }
  return s;
}

// The emulated C-arm adapter: what the host's URBs find on the bulk IN endpoint.
class EmulatedAdapter {
 public:
  EmulatedAdapter() {
    testbed_ = umockdev_testbed_new();
    handler_ = umockdev_ioctl_base_new();
    g_signal_connect_after(handler_, "handle-ioctl", G_CALLBACK(&EmulatedAdapter::on_ioctl), this);
  }
  ~EmulatedAdapter() {
    g_clear_object(&handler_);
    g_clear_object(&testbed_);
    for (auto* u : flying_) umockdev_ioctl_data_unref(u);
    for (auto* u : discarded_) umockdev_ioctl_data_unref(u);
  }

  void plug() {
    {
      std::lock_guard lock(mutex_);
      gone_ = false;
    }
    ASSERT_TRUE(umockdev_testbed_attach_ioctl(testbed_, kNode, handler_, nullptr));
    const std::string dev =
        "P: /devices/usb1/1-1\n"
        "N: bus/usb/001/002\n"
        "E: SUBSYSTEM=usb\nE: DRIVER=usb\nE: BUSNUM=001\nE: DEVNUM=002\n"
        "E: DEVNAME=/dev/bus/usb/001/002\nE: DEVTYPE=usb_device\n"
        "A: busnum=1\\n\nA: devnum=2\\n\nA: bConfigurationValue=1\\n\nA: speed=12\\n\n"
        "H: descriptors=" + descriptor_hex() + "\n";
    ASSERT_TRUE(umockdev_testbed_add_from_string(testbed_, dev.c_str(), nullptr));
  }
  void unplug() {
    {
      std::lock_guard lock(mutex_);
      gone_ = true;
      pending_.clear();
    }
    umockdev_testbed_remove_device(testbed_, "/sys/devices/usb1/1-1");
    umockdev_testbed_detach_ioctl(testbed_, kNode, nullptr);
  }
  void send(const std::vector<std::uint8_t>& bytes) {
    std::lock_guard lock(mutex_);
    pending_.insert(pending_.end(), bytes.begin(), bytes.end());
  }
  std::size_t unread() {
    std::lock_guard lock(mutex_);
    return pending_.size();
  }

 private:
  static constexpr const char* kNode = "/dev/bus/usb/001/002";

  static gboolean on_ioctl(UMockdevIoctlBase*, UMockdevIoctlClient* client, gpointer self) {
    return static_cast<EmulatedAdapter*>(self)->handle(client);
  }

  gboolean handle(UMockdevIoctlClient* client) {
    std::lock_guard lock(mutex_);
    UMockdevIoctlData* arg = umockdev_ioctl_client_get_arg(client);
    switch (umockdev_ioctl_client_get_request(client)) {
      case USBDEVFS_GET_CAPABILITIES: {
        UMockdevIoctlData* d = umockdev_ioctl_data_resolve(arg, 0, sizeof(guint32), nullptr);
        *reinterpret_cast<guint32*>(d->data) = USBDEVFS_CAP_BULK_CONTINUATION | USBDEVFS_CAP_NO_PACKET_SIZE_LIM |
                                               USBDEVFS_CAP_REAP_AFTER_DISCONNECT | USBDEVFS_CAP_ZERO_PACKET;
        umockdev_ioctl_data_unref(d);
        umockdev_ioctl_client_complete(client, 0, 0);
        return TRUE;
      }
      case USBDEVFS_CLAIMINTERFACE:
      case USBDEVFS_RELEASEINTERFACE:
      case USBDEVFS_DISCONNECT_CLAIM:
      case USBDEVFS_CLEAR_HALT:
      case USBDEVFS_SETINTERFACE:
        umockdev_ioctl_client_complete(client, gone_ ? -1 : 0, gone_ ? ENODEV : 0);
        return TRUE;
      case USBDEVFS_SUBMITURB: {
        if (gone_) {
          umockdev_ioctl_client_complete(client, -1, ENODEV);
          return TRUE;
        }
        UMockdevIoctlData* urb = umockdev_ioctl_data_resolve(arg, 0, sizeof(usbdevfs_urb), nullptr);
        const auto* u = reinterpret_cast<usbdevfs_urb*>(urb->data);
        if (u->type != USBDEVFS_URB_TYPE_BULK || u->endpoint != 0x81) {
          umockdev_ioctl_data_unref(urb);
          umockdev_ioctl_client_complete(client, -1, EINVAL);
          return TRUE;
        }
        flying_.push_back(urb);
        umockdev_ioctl_client_complete(client, 0, 0);
        return TRUE;
      }
      case USBDEVFS_REAPURB:
      case USBDEVFS_REAPURBNDELAY: {
        UMockdevIoctlData* urb = nullptr;
        if (!discarded_.empty()) {  // a cancelled (timed-out) read comes back first
          urb = discarded_.front();
          discarded_.pop_front();
          reinterpret_cast<usbdevfs_urb*>(urb->data)->status = -ENOENT;
        } else if (!flying_.empty() && (gone_ || !pending_.empty())) {
          urb = flying_.front();
          flying_.pop_front();
          auto* u = reinterpret_cast<usbdevfs_urb*>(urb->data);
          if (gone_) {
            u->status = -ESHUTDOWN;
            u->actual_length = 0;
          } else {
            // Whole 64-byte packets, a short one ending the transfer, as a device sends.
            const std::size_t n = std::min<std::size_t>(pending_.size(), static_cast<std::size_t>(u->buffer_length));
            std::copy(pending_.begin(), pending_.begin() + static_cast<std::ptrdiff_t>(n), static_cast<std::uint8_t*>(u->buffer));
            pending_.erase(pending_.begin(), pending_.begin() + static_cast<std::ptrdiff_t>(n));
            u->actual_length = static_cast<int>(n);
            u->status = 0;
          }
        }
        if (!urb) {
          umockdev_ioctl_client_complete(client, -1, gone_ ? ENODEV : EAGAIN);
          return TRUE;
        }
        UMockdevIoctlData* ptr = umockdev_ioctl_data_resolve(arg, 0, sizeof(gpointer), nullptr);
        umockdev_ioctl_data_set_ptr(ptr, 0, urb);
        umockdev_ioctl_data_unref(ptr);
        umockdev_ioctl_data_unref(urb);
        umockdev_ioctl_client_complete(client, 0, 0);
        return TRUE;
      }
      case USBDEVFS_DISCARDURB: {
        const auto address = reinterpret_cast<gulong>(*reinterpret_cast<void**>(arg->data));
        for (auto it = flying_.begin(); it != flying_.end(); ++it)
          if ((*it)->client_addr == address) {
            discarded_.push_back(*it);
            flying_.erase(it);
            umockdev_ioctl_client_complete(client, 0, 0);
            return TRUE;
          }
        umockdev_ioctl_client_complete(client, -1, EINVAL);
        return TRUE;
      }
      default:
        return FALSE;
    }
  }

  UMockdevTestbed* testbed_ = nullptr;
  UMockdevIoctlBase* handler_ = nullptr;
  std::mutex mutex_;
  std::deque<std::uint8_t> pending_;
  std::deque<UMockdevIoctlData*> flying_, discarded_;
  bool gone_ = false;
};

}  // namespace evar::test
