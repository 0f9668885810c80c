# Raspberry Pi 5 (BCM2712, Cortex-A76).
set(DENTMARK_BOARD_CPU_FLAGS "-mcpu=cortex-a76")
