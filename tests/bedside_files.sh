#!/usr/bin/env bash
# The bedside service files as install-bedside.sh writes them (docs/SECURITY.md):
# the unit passes systemd's own checks with no warning, its exposure score stays "OK"
# (at most 2.5 of 10), the packet-socket drop-in is only there when asked for, and the
# udev rule names the adapter given. Usage: bedside_files.sh SOURCE_DIR EVARNODE_BINARY
set -euo pipefail
src=$1 bin=$2
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

bash "$src/scripts/install-bedside.sh" --render "$out/plain" --bin "$bin" --carm-usb 1D6B:0104 >/dev/null
cd "$out/plain"
warnings=$(systemd-analyze verify ./evarnode.service 2>&1) || fail "systemd-analyze verify: $warnings"
[ -z "$warnings" ] || fail "systemd-analyze verify warns: $warnings"
systemd-analyze security --offline=true --threshold=25 ./evarnode.service >"$out/security.txt" 2>&1 ||
  fail "exposure above 2.5: $(grep Overall "$out/security.txt")"
grep -q '^CapabilityBoundingSet=$' evarnode.service || fail "the unit grants capabilities"
grep -q '^User=evarnode$' evarnode.service || fail "the unit does not run as the evarnode user"
[ ! -e evarnode.service.d/packet-socket.conf ] || fail "packet-socket drop-in written without --packet-socket"
grep -q 'ATTR{idVendor}=="1d6b", ATTR{idProduct}=="0104", GROUP="evarnode", MODE="0660"' 70-evarnode.rules ||
  fail "udev rule for the USB adapter missing: $(cat 70-evarnode.rules)"
grep -q 'SYMLINK+="evarnode-carm"' 70-evarnode.rules || fail "no stable name for a USB-serial adapter"
grep -Eq '^net\.core\.rmem_max = [0-9]+$' 60-evarnode-gige.conf || fail "no receive-buffer cap for the GigE stream"
[ "$(sed -n 's/^net\.core\.rmem_max = //p' 60-evarnode-gige.conf)" -ge $((8 * 2 * 1024 * 1024)) ] ||
  fail "the receive-buffer cap holds fewer than 8 frames of 1024 x 1024 16-bit"

bash "$src/scripts/install-bedside.sh" --render "$out/raw" --bin "$bin" --packet-socket >/dev/null
grep -q '^AmbientCapabilities=CAP_NET_RAW$' "$out/raw/evarnode.service.d/packet-socket.conf" || fail "no CAP_NET_RAW drop-in"
if grep -q 'idVendor' "$out/raw/70-evarnode.rules"; then fail "a rule for an adapter nobody named"; fi

# A re-install without flags (an update) keeps the choices of the last one; --no-... drops one.
bash "$src/scripts/install-bedside.sh" --render "$out/again" --bin "$bin" --carm-usb 1D6B:0104 --packet-socket >/dev/null
bash "$src/scripts/install-bedside.sh" --render "$out/again" --bin "$bin" >"$out/again.txt"
grep -q 'ATTR{idVendor}=="1d6b", ATTR{idProduct}=="0104"' "$out/again/70-evarnode.rules" ||
  fail "a re-install without flags lost the C-arm adapter's rule"
[ -e "$out/again/evarnode.service.d/packet-socket.conf" ] || fail "a re-install without flags lost the packet socket"
grep -q 'C-arm adapter 1D6B:0104, kept from' "$out/again.txt" || fail "the kept choice was not said: $(cat "$out/again.txt")"
bash "$src/scripts/install-bedside.sh" --render "$out/again" --bin "$bin" --no-packet-socket --no-carm-usb >/dev/null
[ ! -e "$out/again/evarnode.service.d/packet-socket.conf" ] || fail "--no-packet-socket left the drop-in"
if grep -q 'idVendor' "$out/again/70-evarnode.rules"; then fail "--no-carm-usb left the rule"; fi
# A damaged record is named with its line, never run as shell.
printf 'carm_usb=1d6b:0104\npacket_socket=$(touch %s/pwned)\n' "$out" > "$out/again/bedside.conf"
if bash "$src/scripts/install-bedside.sh" --render "$out/again" --bin "$bin" 2>"$out/err.txt"; then
  fail "a damaged bedside.conf was accepted"
fi
[ ! -e "$out/pwned" ] || fail "bedside.conf was run as shell"
grep -q "bedside.conf line 2: 'packet_socket=\$(touch" "$out/err.txt" || fail "unclear error: $(cat "$out/err.txt")"
printf 'carm_usb=1d6b:0104\ncarm_usb=aaaa:bbbb\n' > "$out/again/bedside.conf"
if bash "$src/scripts/install-bedside.sh" --render "$out/again" --bin "$bin" 2>"$out/err.txt"; then fail "a key given twice was accepted"; fi
grep -q "bedside.conf line 2: carm_usb is given twice" "$out/err.txt" || fail "unclear error: $(cat "$out/err.txt")"
printf 'carm_usb=1d6b:0104\r\n' > "$out/again/bedside.conf"
if bash "$src/scripts/install-bedside.sh" --render "$out/again" --bin "$bin" 2>"$out/err.txt"; then fail "a CRLF line was accepted"; fi
grep -q "bedside.conf line 1: a CRLF line ending" "$out/err.txt" || fail "unclear error: $(cat "$out/err.txt")"
if bash "$src/scripts/install-bedside.sh" --render "$out/again" --carm-usb 1d6b:0104 --no-carm-usb 2>"$out/err.txt"; then
  fail "contradicting flags were accepted"
fi
grep -q "contradict each other" "$out/err.txt" || fail "unclear error: $(cat "$out/err.txt")"

if bash "$src/scripts/install-bedside.sh" --render "$out/bad" --carm-usb 1d6b-0104 2>"$out/err.txt"; then
  fail "a malformed VID:PID was accepted"
fi
grep -q "'1d6b-0104' is not VID:PID" "$out/err.txt" || fail "unclear error: $(cat "$out/err.txt")"
echo "bedside files OK: $(grep Overall "$out/security.txt")"
