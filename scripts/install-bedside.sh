#!/usr/bin/env bash
# Installs evarnode as the hardened bedside service (docs/SECURITY.md): the binary, a
# dedicated system user, the systemd unit, the udev rule for the C-arm adapter, the GigE
# receive-buffer cap (sysctl) and a starting /etc/evarnode/node.json (kept if present).
# Idempotent; needs root.
#
#   sudo scripts/install-bedside.sh [--carm-usb VID:PID] [--grabber-usb VID:PID] [--packet-socket]
#   scripts/install-bedside.sh --render DIR [--bin PATH] [...]   (writes the files into DIR only)
#
# --carm-usb      the C-arm adapter (a libusb device for "carm": "usb:VID:PID", or the
#                 USB-serial converter behind "serial:/dev/evarnode-carm"); lsusb shows it
# --grabber-usb   a USB frame grabber, to be named /dev/evarnode-grabber
# --packet-socket grant CAP_NET_RAW for Aravis's packet socket (GigE at high rates)
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
render="" bin=/usr/local/bin/evarnode carm="" grabber="" packet_socket=0
usage() { sed -n '2,13p' "$0" | sed 's/^# \{0,1\}//'; exit "${1:-0}"; }
while [ $# -gt 0 ]; do
  case "$1" in
    --render) render=${2:?--render needs a directory}; shift 2 ;;
    --bin) bin=${2:?--bin needs a path}; shift 2 ;;
    --carm-usb) carm=${2:?--carm-usb needs VID:PID}; shift 2 ;;
    --grabber-usb) grabber=${2:?--grabber-usb needs VID:PID}; shift 2 ;;
    --packet-socket) packet_socket=1; shift ;;
    -h|--help) usage 0 ;;
    *) echo "install-bedside.sh: unknown argument '$1'" >&2; usage 2 >&2 ;;
  esac
done
for id in "$carm" "$grabber"; do
  if [ -n "$id" ] && ! [[ "$id" =~ ^[0-9a-fA-F]{4}:[0-9a-fA-F]{4}$ ]]; then
    echo "install-bedside.sh: '$id' is not VID:PID (four hexadecimal digits each, as lsusb prints)" >&2
    exit 2
  fi
done

# The files, into a staging directory.
stage=$(mktemp -d)
trap 'rm -rf "$stage"' EXIT
escaped_bin=$(printf '%s' "$bin" | sed 's/[&|\\]/\\&/g')
sed "s|/usr/local/bin/evarnode|$escaped_bin|" "$root/scripts/bedside/evarnode.service" > "$stage/evarnode.service"
cp "$root/scripts/bedside/evarnode-packet-socket.conf" "$stage/packet-socket.conf"
{
  echo "# evarnode bedside devices (written by scripts/install-bedside.sh; docs/SECURITY.md)."
  echo "# V4L2 grabbers are group \"video\" and serial ports group \"dialout\" on Debian already;"
  echo "# the service user is in both. This file adds the C-arm adapter and stable names."
  if [ -n "$carm" ]; then
    v=${carm%%:*} p=${carm##*:}
    v=${v,,} p=${p,,}
    echo "SUBSYSTEM==\"usb\", ENV{DEVTYPE}==\"usb_device\", ATTR{idVendor}==\"$v\", ATTR{idProduct}==\"$p\", GROUP=\"evarnode\", MODE=\"0660\""
    echo "SUBSYSTEM==\"tty\", ATTRS{idVendor}==\"$v\", ATTRS{idProduct}==\"$p\", GROUP=\"dialout\", MODE=\"0660\", SYMLINK+=\"evarnode-carm\""
  fi
  if [ -n "$grabber" ]; then
    v=${grabber%%:*} p=${grabber##*:}
    v=${v,,} p=${p,,}
    echo "SUBSYSTEM==\"video4linux\", ATTRS{idVendor}==\"$v\", ATTRS{idProduct}==\"$p\", ATTR{index}==\"0\", GROUP=\"video\", MODE=\"0660\", SYMLINK+=\"evarnode-grabber\""
  fi
} > "$stage/70-evarnode.rules"

if [ -n "$render" ]; then
  mkdir -p "$render/evarnode.service.d"
  cp "$stage/evarnode.service" "$stage/70-evarnode.rules" "$root/scripts/bedside/60-evarnode-gige.conf" "$render/"
  [ "$packet_socket" = 1 ] && cp "$stage/packet-socket.conf" "$render/evarnode.service.d/"
  echo "evarnode: bedside files written to $render"
  exit 0
fi

[ "$(id -u)" -eq 0 ] || { echo "install-bedside.sh: run as root (sudo), or use --render DIR" >&2; exit 1; }
EVAR_BUILD_DIR=${EVAR_BUILD_DIR:-$root/build} "$root/scripts/build.sh"
install -D -m 0755 "${EVAR_BUILD_DIR:-$root/build}/app/evarnode" "$bin"
getent group evarnode >/dev/null || addgroup --system evarnode
id evarnode >/dev/null 2>&1 || adduser --system --ingroup evarnode --home /var/lib/evarnode --no-create-home evarnode
install -D -m 0644 "$stage/evarnode.service" /etc/systemd/system/evarnode.service
if [ "$packet_socket" = 1 ]; then
  install -D -m 0644 "$stage/packet-socket.conf" /etc/systemd/system/evarnode.service.d/packet-socket.conf
else
  rm -f /etc/systemd/system/evarnode.service.d/packet-socket.conf
fi
install -D -m 0644 "$stage/70-evarnode.rules" /etc/udev/rules.d/70-evarnode.rules
install -D -m 0644 "$root/scripts/bedside/60-evarnode-gige.conf" /etc/sysctl.d/60-evarnode-gige.conf
sysctl -q -p /etc/sysctl.d/60-evarnode-gige.conf ||
  echo "evarnode: could not raise net.core.rmem_max here (a container?); it applies from the next boot" >&2
install -D -m 0644 "$root/docs/SECURITY.md" /usr/local/share/doc/evarnode/SECURITY.md
if [ ! -e /etc/evarnode/node.json ]; then
  install -d -m 0750 -g evarnode /etc/evarnode
  install -m 0640 -g evarnode "$root/scripts/bedside/node.json" /etc/evarnode/node.json
  echo "evarnode: edit /etc/evarnode/node.json (scene, registration, detector, grabber, C-arm link)"
fi
if command -v udevadm >/dev/null; then
  udevadm control --reload && udevadm trigger --subsystem-match=usb --subsystem-match=tty --subsystem-match=video4linux ||
    echo "evarnode: udev is not running here; the rule applies from the next boot" >&2
fi
if [ -d /run/systemd/system ]; then
  systemctl daemon-reload
  systemctl enable evarnode.service
  echo "evarnode: installed; start with: systemctl start evarnode   (log: journalctl -u evarnode)"
else
  echo "evarnode: installed; systemd is not running here, so the unit was not enabled"
fi
