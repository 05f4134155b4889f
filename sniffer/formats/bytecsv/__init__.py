"""Byte CSV (`t_s,channel,byte_hex,flags`): its reader and its writer."""
