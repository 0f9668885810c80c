# NXP i.MX 8M Plus (Cortex-A53).
set(DENTMARK_BOARD_CPU_FLAGS "-mcpu=cortex-a53")
