/* thesis table 7.1 (figure 1): a glass sphere in front of a red opaque sphere.
   Colours in 0-255 as printed in the thesis (any colour value above 1
   makes the whole file 0-255). */

V 200 200        /* viewport size in pixels: width height */
C 0 0 10         /* camera position */
A 1 1 -1         /* target point the camera looks at */
U 0 1 0          /* camera up vector */
B 45 45          /* camera opening angles in degrees: horizontal vertical */

L 1              /* number of lights */
C 100 100 100    /* light colour r g b */
P 10 10 10       /* light position */
I 1              /* brightness */

O 2              /* number of objects */

/* sphere 1: glass lens */
T 0              /* object type: 0 sphere */
C 3 3 3          /* sphere centre */
R 1              /* sphere radius */
S                /* surface definition follows */
#C 100 10 10     /* surface colour r g b */
#A 0.1           /* ka  ambient coefficient */
#D 0.2           /* kd  diffuse coefficient */
#S 0             /* ks  specular (and global reflection) coefficient */
#T 0.7           /* kt  transmission coefficient (0 = opaque) */
#E 80            /* Phong exponent */
#N 1.5171        /* index of refraction */

/* sphere 2: red opaque sphere */
T 0
C 1 1 -1
R 2
S
#C 250 0 0
#A 0.1
#D 0.9
#S 0
#T 0
#E 70
#N 1.0
