# Generic Armv8-A: runs under qemu-user and qemu-system 'virt'.
set(DENTMARK_BOARD_CPU_FLAGS "-march=armv8-a")
