"""Operations on motions: ``Motion`` → ``Motion`` or arrays (retarget, edit, segment, analyse)."""
