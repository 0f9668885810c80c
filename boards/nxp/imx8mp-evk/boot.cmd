# U-Boot boot script (boot.scr: mkimage -A arm64 -T script -C none -d boot.cmd boot.scr)
# for RAUC's uboot backend, after RAUC's contrib/uboot.sh: BOOT_ORDER lists the slots
# by preference, BOOT_<slot>_LEFT the attempts a slot has left; each boot takes one,
# `rauc status mark-good` (after dentmark's health check) gives them back.
test -n "${BOOT_ORDER}" || setenv BOOT_ORDER "A B"
test -n "${BOOT_A_LEFT}" || setenv BOOT_A_LEFT 3
test -n "${BOOT_B_LEFT}" || setenv BOOT_B_LEFT 3

setenv rootpart
for BOOT_SLOT in "${BOOT_ORDER}"; do
  if test "x${rootpart}" != "x"; then
    # a slot was chosen
  elif test "x${BOOT_SLOT}" = "xA"; then
    if test ${BOOT_A_LEFT} -gt 0; then
      setexpr BOOT_A_LEFT ${BOOT_A_LEFT} - 1
      setenv rootpart 2
      setenv bootargs "console=ttymxc1,115200 root=PARTLABEL=rootfs-a rootwait rw rauc.slot=A"
    fi
  elif test "x${BOOT_SLOT}" = "xB"; then
    if test ${BOOT_B_LEFT} -gt 0; then
      setexpr BOOT_B_LEFT ${BOOT_B_LEFT} - 1
      setenv rootpart 3
      setenv bootargs "console=ttymxc1,115200 root=PARTLABEL=rootfs-b rootwait rw rauc.slot=B"
    fi
  fi
done

if test -n "${rootpart}"; then
  saveenv
else
  echo "No slot has attempts left: 3 attempts each again"
  setenv BOOT_A_LEFT 3
  setenv BOOT_B_LEFT 3
  saveenv
  reset
fi

load mmc 2:${rootpart} ${kernel_addr_r} /vmlinuz
load mmc 2:${rootpart} ${fdt_addr_r} /usr/lib/linux-image-*/freescale/imx8mp-evk.dtb
load mmc 2:${rootpart} ${ramdisk_addr_r} /initrd.img
booti ${kernel_addr_r} ${ramdisk_addr_r}:${filesize} ${fdt_addr_r}
