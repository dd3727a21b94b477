/*
 * commands.h - the subcommands of wfiscene besides scene rendering.  Each
 * takes argv after the subcommand name (argv[0] is the subcommand) and
 * returns an exit status (enum wfs_exit).
 */
#ifndef WFS_COMMANDS_H
#define WFS_COMMANDS_H

int psf_main(int argc, char **argv);       /* wfiscene psf: write PSF grids */
int preview_main(int argc, char **argv);   /* wfiscene preview: PNG images */
int merge_main(int argc, char **argv);     /* wfiscene merge: join split runs */

#endif
